//! The browser viewer in headless Chromium, over WebDriver: a real server
//! on port 0 serves the page, the wasm and the stream; the canvas must
//! show `farfield render`'s image of the camera in the URL, on WebGPU
//! (SwiftShader) and on WebGL2; a drag must move the view and the page
//! refine again to the new view's image; a server restart must leave the
//! image up and the viewer resume asking only for what it lacks; a PLP
//! scene must show `farfield render --budget`'s image at the budget in the
//! page's address; a page following a demo session must rest at each view
//! its presenter shows.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Duration;

use farfield_memory_server::web_assets::{self, WebViewer};
use farfield_memory_server::{RunningServer, ServerConfig, start};
use farfield_render::Kernel;
use farfield_tests::scratch;
use serde_json::Value;

use super::webdriver::{Browser, Graphics};
use super::{
    PlpRows, bunny_in, camera_of_fragment, have, lit, missing, psnr, reference, reference_with,
};
use crate::streaming::runtime;

const SIZE: (u32, u32) = (320, 240);
/// SwiftShader draws on the CPU, and two tests may share it.
const WAIT: Duration = Duration::from_secs(120);
const START: &str = "eye=0.25,0.2,0.15&target=-0.017,0.11,-0.0015&fov=45";

/// One browser at a time: each runs its GPU on the CPU.
static ONE_BROWSER: Mutex<()> = Mutex::new(());

const REFINED: &str = "return document.getElementById('farfield').dataset.refined === 'true'";
const REPORT: &str = "const c = document.getElementById('farfield'); \
    return {failed: document.body.dataset.failed || null, \
            message: document.getElementById('message').innerText, \
            status: c.dataset.status || null, hash: location.hash}";

/// The browser viewer the server finds (the one built into it, where it
/// could be built), or `None` (having said why) when it has none.
fn web_dir() -> Option<WebViewer> {
    let viewer = web_assets::find();
    match web_assets::ready(viewer.as_ref()) {
        Ok(()) => viewer,
        Err(why) => {
            missing(&format!(
                "the browser tests need the viewer ({why}; {}): build with the wasm32 target, or run web/build",
                web_assets::not_embedded()
            ));
            None
        }
    }
}

/// The tools and files the browser tests need, or `None` when a tool is missing.
fn setup(name: &str) -> Option<(PathBuf, PathBuf, WebViewer)> {
    let (dir, web) = browser_ready(name)?;
    let bunny = bunny_in(&dir)?;
    Some((dir, bunny, web))
}

/// A scratch folder and the built viewer, or `None` when a tool is missing.
fn browser_ready(name: &str) -> Option<(PathBuf, WebViewer)> {
    for tool in ["chromium", "chromedriver"] {
        if !have(tool) {
            missing(&format!(
                "the browser tests need {tool} (apt-get install chromium chromium-driver)"
            ));
            return None;
        }
    }
    let web = web_dir()?;
    Some((scratch(name), web))
}

async fn serve(dir: &std::path::Path, web: &WebViewer, listen: SocketAddr) -> RunningServer {
    start(ServerConfig {
        web: match web {
            WebViewer::Folder(dir) => Some(dir.clone()),
            WebViewer::Embedded(_) => None,
        },
        ..ServerConfig::new(dir, listen)
    })
    .await
    .expect("server starts")
}

fn status(browser: &Browser) -> Value {
    let text = browser.eval("return document.getElementById('farfield').dataset.status || 'null'");
    serde_json::from_str(text.as_str().unwrap_or("null")).unwrap_or(Value::Null)
}

/// Waits for the page to be refined and checks its picture against the
/// headless render of the camera in its address. Returns that address
/// fragment and the picture.
fn check_refined(browser: &Browser, bunny: &std::path::Path, what: &str) -> (String, Vec<u8>) {
    browser.wait_for(what, REFINED, REPORT, WAIT);
    let hash = browser.eval("return location.hash");
    let hash = hash.as_str().unwrap_or_default().to_owned();
    let (w, h, shot) = browser.canvas_pixels();
    assert_eq!((w, h), SIZE, "the canvas fills the viewport");
    // What the user sees is the canvas.
    let (sw, sh, seen) = browser.screenshot();
    assert_eq!((sw, sh), SIZE, "the viewport");
    let same = psnr(&shot, &seen, SIZE.0, SIZE.1);
    assert!(
        same >= 40.0,
        "{what}: the screen differs from the canvas ({same:.1} dB)"
    );
    let expected = reference(bunny, camera_of_fragment(&hash), SIZE.0, SIZE.1).unwrap();
    let db = psnr(&expected, &shot, SIZE.0, SIZE.1);
    eprintln!(
        "{what}: {db:.1} dB against headless, {} lit pixels",
        lit(&shot)
    );
    assert!(lit(&shot) > 2000, "{what}: the canvas shows the bunny");
    assert!(
        db >= 30.0,
        "{what}: the canvas differs from the headless render ({db:.1} dB)"
    );
    (hash, shot)
}

#[test]
fn the_browser_shows_the_headless_image_on_webgpu_and_webgl_and_refines_after_a_drag() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, bunny, web)) = setup("viewer-browser") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let addr = server.local_addr();
    let browser = Browser::start(SIZE.0, SIZE.1);
    for (backend, adapter) in [("webgpu", "WebGpu"), ("webgl", "Gl")] {
        browser.goto(&format!(
            "http://{addr}/view/bunny?panel=0&backend={backend}#{START}"
        ));
        let (hash, first) = check_refined(&browser, &bunny, backend);
        assert_eq!(
            camera_of_fragment(&hash),
            camera_of_fragment(START),
            "{backend}: the page opens at the link's camera"
        );
        let used = status(&browser)["adapter"]
            .as_str()
            .unwrap_or_default()
            .to_owned();
        assert!(used.contains(adapter), "{backend}: drawn on {used:?}");
        // A script's screenshot (`farfield.screenshot()`, the button's) is
        // the picture, opaque.
        browser.eval(
            "delete document.getElementById('farfield').dataset.screenshot; \
             window.farfield.screenshot(); return null",
        );
        browser.wait_for(
            &format!("{backend}: the screenshot"),
            "return !!document.getElementById('farfield').dataset.screenshot",
            REPORT,
            WAIT,
        );
        let (w, h, shot) = browser.data_png("screenshot");
        assert_eq!((w, h), SIZE, "{backend}: the screenshot's size");
        let clear = shot.chunks(4).filter(|p| p[3] != 255).count();
        assert_eq!(
            clear, 0,
            "{backend}: {clear} pixels of the screenshot are not opaque"
        );
        let db = psnr(&first, &shot, SIZE.0, SIZE.1);
        assert!(
            lit(&shot) > 2000 && db >= 30.0,
            "{backend}: the screenshot is not the picture ({} lit, {db:.1} dB)",
            lit(&shot)
        );
        if backend == "webgpu" {
            browser.drag((160, 120), (90, 30), 10);
            let moved = format!(
                "return document.getElementById('farfield').dataset.refined === 'true' \
                 && location.hash !== {hash:?}"
            );
            browser.wait_for("refined after the drag", &moved, REPORT, WAIT);
            let (after, second) = check_refined(&browser, &bunny, "after the drag");
            assert_ne!(after, hash);
            let change = psnr(&first, &second, SIZE.0, SIZE.1);
            assert!(change < 25.0, "the picture did not change ({change:.1} dB)");
        }
    }
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn the_browser_viewer_keeps_its_image_through_a_server_restart() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, bunny, web)) = setup("viewer-restart") else {
        return;
    };
    let rt = runtime();
    let first = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let addr = first.local_addr();
    let browser = Browser::start(SIZE.0, SIZE.1);
    browser.goto(&format!("http://{addr}/view/bunny?panel=0#{START}"));
    let (_, before) = check_refined(&browser, &bunny, "before the restart");
    rt.block_on(first.shutdown()).unwrap();
    browser.wait_for(
        "the page says the server went away",
        "return document.getElementById('farfield').dataset.connection === 'reconnecting'",
        REPORT,
        WAIT,
    );
    let (_, _, during) = browser.screenshot();
    assert!(
        lit(&during) > 2000,
        "the image stays while the server is away"
    );
    let second = rt.block_on(serve(&dir, &web, addr));
    browser.wait_for(
        "the page reconnects",
        "return document.getElementById('farfield').dataset.connection === 'connected'",
        REPORT,
        WAIT,
    );
    let (_, after) = check_refined(&browser, &bunny, "after the restart");
    assert!(psnr(&before, &after, SIZE.0, SIZE.1) >= 30.0);
    // It had every page it needed, so it asked for none: the two pages the
    // new server sent are the root directory page and page 0, which every
    // session gets with the header.
    let served = second.metrics().pages_served;
    assert!(
        served <= 2,
        "the viewer asked again for pages it had ({served} sent)"
    );
    drop(browser);
    rt.block_on(second.shutdown()).unwrap();
}

/// A PLP scene at `?plp_budget=2`: the canvas shows what `farfield render
/// --budget 2%` draws, not the whole scene.
#[test]
fn the_browser_draws_plp_on_the_budget_in_its_address() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, web)) = browser_ready("viewer-browser-plp") else {
        return;
    };
    let Some(rows) = PlpRows::build(&dir, SIZE) else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    for backend in ["webgpu", "webgl"] {
        browser.goto(&format!(
            "http://{}/view/rows?panel=0&backend={backend}&plp_budget={}#{}",
            server.local_addr(),
            PlpRows::PERCENT,
            rows.start
        ));
        browser.wait_for(backend, REFINED, REPORT, WAIT);
        let hash = browser.eval("return location.hash");
        assert_eq!(
            camera_of_fragment(hash.as_str().unwrap_or_default()),
            rows.camera,
            "{backend}: the page opens at the link's camera"
        );
        let (w, h, shot) = browser.canvas_pixels();
        assert_eq!((w, h), SIZE);
        rows.check(&shot, SIZE, backend);
    }
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn an_unknown_scene_gets_a_page_that_links_back_to_the_list() {
    let dir = scratch("viewer-unknown");
    let rt = runtime();
    let empty = WebViewer::Folder(dir.clone());
    let server = rt.block_on(serve(&dir, &empty, "127.0.0.1:0".parse().unwrap()));
    let (status, body) = rt.block_on(crate::serve::support::http_get(
        server.local_addr(),
        "/view/nope%3Cb%3E",
    ));
    assert_eq!(status, 404);
    assert!(body.contains("No scene named “nope&lt;b&gt;”"), "{body}");
    assert!(body.contains("<a href=\"/\">"), "{body}");
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn a_browser_without_webgpu_or_webgl2_is_told_so() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-no-gpu") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::with_graphics(SIZE.0, SIZE.1, false);
    browser.goto(&format!("http://{}/view/bunny", server.local_addr()));
    browser.wait_for(
        "the page says why it cannot draw",
        "return document.body.dataset.failed === 'true'",
        REPORT,
        WAIT,
    );
    let text = browser.eval("return document.getElementById('message').innerText");
    let text = text.as_str().unwrap_or_default();
    assert!(text.contains("neither WebGPU nor WebGL2"), "{text}");
    assert!(
        text.contains("the scenes this server has"),
        "a link back: {text}"
    );
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// The panel's screenshot button saves the picture on WebGPU and on WebGL
/// (on WebGL its file was all transparent: the click's frame ran before
/// the canvas was drawn). The button is clicked where an 800x600 page
/// shows it.
#[test]
fn the_screenshot_button_saves_the_picture_on_webgpu_and_webgl() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-screenshot") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(800, 600);
    for backend in ["webgpu", "webgl"] {
        browser.goto(&format!(
            "http://{}/view/bunny?backend={backend}#{START}",
            server.local_addr()
        ));
        browser.wait_for(backend, REFINED, REPORT, WAIT);
        browser.eval("delete document.getElementById('farfield').dataset.screenshot; return null");
        // Where the panel says its button is, and within the page.
        let button = status(&browser)["screenshot_button"].clone();
        let at = |i: usize| button[i].as_f64().unwrap_or(f64::NAN);
        let (x, y) = (at(0) + at(2) / 2.0, at(1) + at(3) / 2.0);
        assert!(
            (0.0..800.0).contains(&x) && (0.0..600.0).contains(&y),
            "{backend}: the button at {button}"
        );
        browser.click(x as i64, y as i64);
        browser.wait_for(
            &format!("{backend}: the screenshot"),
            "return !!document.getElementById('farfield').dataset.screenshot",
            REPORT,
            WAIT,
        );
        let (_, _, shot) = browser.data_png("screenshot");
        let clear = shot.chunks(4).filter(|p| p[3] != 255).count();
        assert_eq!(clear, 0, "{backend}: {clear} pixels are not opaque");
        assert!(
            lit(&shot) > 5000,
            "{backend}: the screenshot is empty ({} lit pixels)",
            lit(&shot)
        );
    }
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// A window wider than the device's largest texture (9000 against
/// WebGPU's 8192) draws the scene on a canvas held within that size, with
/// no GPU error (it used to show nothing but the error, or panic). One
/// side past the limit is enough, and keeps a software GPU's frames short
/// (9000 x 9000 took over 30 s a frame on a loaded CI machine).
#[test]
fn a_9000_pixel_wide_window_draws_within_the_devices_limits() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-huge") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(9000, 1200);
    for backend in ["webgpu", "webgl"] {
        browser.goto(&format!(
            "http://{}/view/bunny?panel=0&backend={backend}",
            server.local_addr()
        ));
        let drawn = "const s = JSON.parse(document.getElementById('farfield').dataset.status || '{}'); \
                     return s.nodes_drawn > 0 || !!s.error";
        browser.wait_for(&format!("{backend}: a first image"), drawn, REPORT, WAIT);
        let s = status(&browser);
        assert!(s["error"].is_null(), "{backend}: {}", s["error"]);
        assert!(s["nodes_drawn"].as_u64().unwrap_or(0) > 0, "{backend}: {s}");
        let side = browser.eval(
            "const c = document.getElementById('farfield'); return Math.max(c.width, c.height)",
        );
        let side = side.as_u64().unwrap_or(u64::MAX);
        assert!(
            (8000..=8192).contains(&side),
            "{backend}: a canvas {side} pixels wide"
        );
    }
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// A browser whose WebGPU device is lost once drawing starts (Chromium on
/// SwiftShader without the Vulkan flags): the page starts again on WebGL2
/// at the same camera and says why (it used to show nothing and report
/// itself refined).
#[test]
fn a_lost_webgpu_device_starts_the_page_again_on_webgl2() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-device-lost") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::with(SIZE.0, SIZE.1, Graphics::LosesWebGpu);
    browser.goto(&format!(
        "http://{}/view/bunny?panel=0#{START}",
        server.local_addr()
    ));
    let on_webgl = "return location.search.includes('backend=webgl') \
                    && document.getElementById('farfield').dataset.refined === 'true'";
    browser.wait_for("refined on WebGL2", on_webgl, REPORT, WAIT);
    let s = status(&browser);
    let adapter = s["adapter"].as_str().unwrap_or_default();
    assert!(adapter.contains(" / Gl"), "drawn on {adapter:?}");
    assert!(s["error"].is_null(), "{}", s["error"]);
    let notice = s["notice"].as_str().unwrap_or_default();
    assert!(notice.contains("WebGPU's device was lost"), "{notice:?}");
    // The notice is on the picture for a while: the bunny is there, at
    // the link's camera.
    let drawn = s["nodes_drawn"].as_u64().unwrap_or(0);
    assert!(drawn > 1000, "the bunny is drawn: {drawn} nodes");
    let (_, _, shot) = browser.canvas_pixels();
    assert!(lit(&shot) > 2000, "the canvas shows the bunny");
    let hash = browser.eval("return location.hash");
    let hash = hash.as_str().unwrap_or_default();
    assert_eq!(
        camera_of_fragment(hash),
        camera_of_fragment(START),
        "the same camera"
    );
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// A damaged link opens the scene at its default view, refined, and says
/// what it ignored (it used to stop the viewer: a black page).
#[test]
fn a_damaged_link_opens_the_default_view_and_says_what_was_ignored() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-damaged-link") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    browser.goto(&format!(
        "http://{}/view/bunny?panel=0#eye=1,2&target=x",
        server.local_addr()
    ));
    browser.wait_for("refined at the default view", REFINED, REPORT, WAIT);
    let notice = status(&browser)["notice"]
        .as_str()
        .unwrap_or_default()
        .to_owned();
    assert!(
        notice.contains("was ignored") && notice.contains("eye=1,2"),
        "{notice:?}"
    );
    let drawn = status(&browser)["nodes_drawn"].as_u64().unwrap_or(0);
    assert!(
        drawn > 1000,
        "the default view draws the bunny: {drawn} nodes"
    );
    let (_, _, shot) = browser.canvas_pixels();
    assert!(lit(&shot) > 2000, "the default view shows the bunny");
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// Waits for the view to be refined at a camera other than `previous`'s
/// (the page's address); returns the new address.
fn refined_away_from(browser: &Browser, previous: &str, what: &str) -> String {
    let moved = format!(
        "return document.getElementById('farfield').dataset.refined === 'true' \
         && location.hash !== {previous:?}"
    );
    browser.wait_for(what, &moved, REPORT, WAIT);
    browser
        .eval("return location.hash")
        .as_str()
        .unwrap_or_default()
        .to_owned()
}

/// Eye and target of an address's camera.
fn eye_target(fragment: &str) -> (glam::DVec3, glam::DVec3) {
    match camera_of_fragment(fragment) {
        farfield_client::camera_spec::CameraSpec::Eye { eye, target, .. } => (eye, target),
        other => panic!("not an eye camera: {other:?}"),
    }
}

#[test]
fn one_finger_orbits_two_fingers_pinch_to_zoom_and_w_flies_forward() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-touch") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    browser.goto(&format!(
        "http://{}/view/bunny?panel=0#{START}",
        server.local_addr()
    ));
    browser.wait_for("refined", REFINED, REPORT, WAIT);
    let start = browser
        .eval("return location.hash")
        .as_str()
        .unwrap_or_default()
        .to_owned();
    let (eye0, target0) = eye_target(&start);

    // One finger across the screen: the eye circles the target.
    let path: Vec<(i64, i64)> = (0..5).map(|i| (160 + 20 * i, 120 + 5 * i)).collect();
    browser.touch(&[&path]);
    let orbited = refined_away_from(&browser, &start, "refined after a one-finger drag");
    let (eye1, target1) = eye_target(&orbited);
    assert!(
        (target1 - target0).length() < 1e-9,
        "an orbit keeps the target"
    );
    let (d0, d1) = ((eye0 - target0).length(), (eye1 - target1).length());
    assert!(
        (d1 - d0).abs() < 1e-6 * d0,
        "and the distance: {d0} -> {d1}"
    );
    assert!(
        (eye1 - eye0).length() > 0.05 * d0,
        "the eye moved: {eye0} -> {eye1}"
    );

    // Two fingers apart around the centre: closer, same direction.
    let left: Vec<(i64, i64)> = (0..5).map(|i| (150 - 10 * i, 120)).collect();
    let right: Vec<(i64, i64)> = (0..5).map(|i| (170 + 10 * i, 120)).collect();
    browser.touch(&[&left, &right]);
    let pinched = refined_away_from(&browser, &orbited, "refined after a pinch");
    let (eye2, target2) = eye_target(&pinched);
    let d2 = (eye2 - target2).length();
    assert!(
        d2 < 0.8 * d1,
        "spreading two fingers zooms in: {d1} -> {d2}"
    );
    let before = (eye1 - target1).normalize();
    let after = (eye2 - target2).normalize();
    assert!(before.dot(after) > 0.99, "a pinch does not turn the view");

    // W (with the page focused by a click in a corner): forward along the view.
    browser.click(5, 5);
    // Held long enough for a loaded machine's slow frames to see it down.
    browser.hold_key("w", 2500);
    let flown = refined_away_from(&browser, &pinched, "refined after flying forward");
    let (eye3, target3) = eye_target(&flown);
    let step = eye3 - eye2;
    assert!(step.length() > 0.0);
    assert!(
        step.normalize().dot(-after) > 0.99,
        "W moves the eye along the view: {eye2} -> {eye3}"
    );
    assert!(
        ((target3 - eye3).length() - d2).abs() < 1e-9 * d2,
        "the view's depth stays"
    );
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// Within a millionth of the scene's size.
fn near(a: glam::DVec3, b: glam::DVec3) -> bool {
    (a - b).length() <= 1e-6 * b.length().max(1.0)
}

/// A page opened at `?session=demo&role=follow` draws the presenter's
/// view, and follows it when the presenter moves.
#[test]
fn the_browser_follows_a_demo_sessions_presenter() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((_, web)) = browser_ready("viewer-browser-demo") else {
        return;
    };
    let (dir, _) = crate::streaming::scenes("viewer-browser-demo-scenes");
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let url = format!("http://{}", server.local_addr());
    let mut presenter = crate::demo_sessions::Member::join(&url, true);
    presenter.until("the seat", |m| {
        m.link.is_presenting() && m.viewer.header().is_some()
    });
    let first = crate::demo_sessions::orbit(40.0, &presenter);
    presenter
        .link
        .show(&mut presenter.viewer, &first, Vec::new());
    let browser = Browser::start(SIZE.0, SIZE.1);
    browser.goto(&format!(
        "{url}/view/island?panel=0&backend=webgl&session=demo&role=follow"
    ));
    let next = crate::demo_sessions::orbit(160.0, &presenter);
    for (what, camera) in [("the first view", first), ("the next view", next)] {
        if camera == next {
            presenter
                .link
                .show(&mut presenter.viewer, &camera, Vec::new());
        }
        let at = "return document.getElementById('farfield').dataset.refined === 'true' \
             && (JSON.parse(document.getElementById('farfield').dataset.status || '{}').demo || '').startsWith('following demo') \
             && location.hash.length > 1";
        browser.wait_for(what, at, REPORT, WAIT);
        let started = std::time::Instant::now();
        loop {
            let hash = browser.eval("return location.hash");
            let (eye, target) = eye_target(hash.as_str().unwrap_or_default());
            if near(eye, camera.eye) && near(target, camera.target) {
                break;
            }
            assert!(
                started.elapsed() < WAIT,
                "{what}: the page rests at {eye}, {target}, not the presenter's {}, {}",
                camera.eye,
                camera.target
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    let sessions = server.sessions();
    assert_eq!(sessions[0].followers, 1, "{sessions:?}");
    drop(browser);
    drop(presenter);
    rt.block_on(server.shutdown()).unwrap();
}

/// Eye-dome lighting (`?edl=1`) draws what `farfield render --edl` draws,
/// on WebGPU and WebGL2, with flat and paraboloid splats, and darkens the
/// bunny's creases and steps against the plain picture.
#[test]
fn eye_dome_lighting_in_the_browser_draws_the_headless_image() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, bunny, web)) = setup("viewer-edl") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    let camera = camera_of_fragment(START);
    let brightness = |rgba: &[u8]| -> u64 {
        rgba.chunks(4)
            .map(|p| u64::from(p[0]) + u64::from(p[1]) + u64::from(p[2]))
            .sum()
    };
    for kernel in [Kernel::Square, Kernel::Paraboloid] {
        let edl = Some(farfield_render::Edl::default());
        let shaded = reference_with(&bunny, camera, SIZE, |job| {
            (job.kernel, job.edl) = (kernel, edl);
        })
        .unwrap();
        let plain = reference_with(&bunny, camera, SIZE, |job| job.kernel = kernel).unwrap();
        let darker = brightness(&shaded) as f64 / brightness(&plain) as f64;
        let apart = psnr(&plain, &shaded, SIZE.0, SIZE.1);
        let name = kernel.name();
        eprintln!(
            "{name}, headless: EDL keeps {darker:.3} of the brightness, {apart:.1} dB from plain"
        );
        assert!(darker < 0.97, "{name}: EDL darkens little: {darker:.3}");
        let query = format!("kernel={name}&edl=1");
        draws_like(&browser, &server, &query, &shaded, &plain);
    }
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// Colouring by elevation (`?color=elevation`) draws what `farfield render
/// --color elevation` draws, on WebGPU and WebGL2: the bunny (Y-up, built
/// upright) runs from the ramp's violet blue at its feet to red at the
/// tips of its ears.
#[test]
fn colour_by_elevation_in_the_browser_draws_the_headless_ramp() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, bunny, web)) = setup("viewer-elevation") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    let camera = camera_of_fragment(START);
    let ramp = farfield_render::ColorBy::Elevation(None);
    let expected = reference_with(&bunny, camera, SIZE, |job| job.color_by = ramp).unwrap();
    let plain = reference(&bunny, camera, SIZE.0, SIZE.1).unwrap();
    // Red against blue in the top and bottom thirds of the rows the
    // bunny covers.
    let lit_pixel = |rgba: &[u8], x: u32, y: u32| -> Option<[u8; 3]> {
        let p = &rgba[((y * SIZE.0 + x) * 4) as usize..][..4];
        (u32::from(p[0]) + u32::from(p[1]) + u32::from(p[2]) > 30).then_some([p[0], p[1], p[2]])
    };
    let rows: Vec<u32> = (0..SIZE.1)
        .filter(|&y| (0..SIZE.0).any(|x| lit_pixel(&expected, x, y).is_some()))
        .collect();
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    let third = (last - first) / 3;
    let warmth = |rows: std::ops::Range<u32>| -> f64 {
        let (mut red, mut blue) = (0u64, 0u64);
        for y in rows {
            for p in (0..SIZE.0).filter_map(|x| lit_pixel(&expected, x, y)) {
                (red, blue) = (red + u64::from(p[0]), blue + u64::from(p[2]));
            }
        }
        red as f64 / blue.max(1) as f64
    };
    let (top, bottom) = (warmth(first..first + third), warmth(last - third..last + 1));
    eprintln!("headless: red/blue {top:.2} in the top third, {bottom:.2} in the bottom");
    assert!(top > bottom * 1.5, "top {top:.2}, bottom {bottom:.2}");
    draws_like(&browser, &server, "color=elevation", &expected, &plain);
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// The bunny with the page's `query`, on WebGPU and WebGL2, refined: the
/// headless render of `expected` (within 30 dB), and nearer it than the
/// `plain` one.
fn draws_like(
    browser: &Browser,
    server: &RunningServer,
    query: &str,
    expected: &[u8],
    plain: &[u8],
) {
    for backend in ["webgpu", "webgl"] {
        browser.goto(&format!(
            "http://{}/view/bunny?panel=0&backend={backend}&{query}#{START}",
            server.local_addr()
        ));
        browser.wait_for(backend, REFINED, REPORT, WAIT);
        let (_, _, shot) = browser.canvas_pixels();
        let (to_expected, to_plain) = (
            psnr(expected, &shot, SIZE.0, SIZE.1),
            psnr(plain, &shot, SIZE.0, SIZE.1),
        );
        let what = format!(
            "{query}, {backend}: {to_expected:.1} dB from headless, {to_plain:.1} dB from plain"
        );
        eprintln!("{what}");
        assert!(
            to_expected >= 30.0 && to_expected > to_plain + 3.0,
            "{what}"
        );
    }
}

/// The preset views' keys (7 top, 1 front, 3 left) move the camera to look
/// at the scene from that side, and the link says so once it rests.
#[test]
fn preset_view_keys_look_from_above_the_front_and_the_left() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-presets") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    browser.goto(&format!(
        "http://{}/view/bunny?panel=0#{START}",
        server.local_addr()
    ));
    browser.wait_for("refined", REFINED, REPORT, WAIT);
    let start = eye_target(START);
    for (key, side) in [
        ("7", glam::DVec3::Z),
        ("1", -glam::DVec3::Y),
        ("3", -glam::DVec3::X),
    ] {
        let before = browser.eval("return location.hash");
        let before = before.as_str().unwrap_or_default().to_owned();
        browser.hold_key(key, 50);
        let after = refined_away_from(&browser, &before, &format!("key {key}"));
        let (eye, target) = eye_target(&after);
        let back = (eye - target).normalize();
        assert!(back.dot(side) > 0.99, "key {key}: looking from {back}");
        assert!(
            (target - start.1).length() < 0.2,
            "key {key}: looking at {target}, not the bunny"
        );
    }
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// The measuring tool (M, then a click on each point) measures between
/// the points picked, within 1 % of the true distance: on a flat square
/// of points 100 units wide, looked at from above and aside, the true
/// points are where the clicked pixels' rays meet its plane.
#[test]
fn a_measurement_between_two_picked_points_is_the_true_distance() {
    use farfield_builder::scene::{Geometry, Primitives, Scene};
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, _, web)) = setup("viewer-measure") else {
        return;
    };
    let positions = (0..=200)
        .flat_map(|y| (0..=200).map(move |x| glam::DVec3::new(x as f64 * 0.5, y as f64 * 0.5, 0.0)))
        .collect();
    let scene = Scene::single(Geometry::new("plane", positions, Primitives::Points));
    farfield_store::write_atomic(&dir.join("plane.ff"), &crate::build(scene)).unwrap();
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    let link = "eye=50,-10,90&target=50,50,0&fov=45";
    browser.goto(&format!(
        "http://{}/view/plane?panel=0#{link}",
        server.local_addr()
    ));
    browser.wait_for("refined", REFINED, REPORT, WAIT);
    let (eye, target) = eye_target(link);
    let camera = farfield_protocol::camera::Camera {
        eye,
        target,
        up: glam::DVec3::Z,
        fov_y_deg: 45.0,
        width: SIZE.0,
        height: SIZE.1,
    };
    // Where the ray through a pixel's center meets the plane z = 0.
    let on_plane = |(x, y): (i64, i64)| -> glam::DVec3 {
        let view = camera.view(1.0);
        let ndc_x = (x as f64 + 0.5) / f64::from(SIZE.0) * 2.0 - 1.0;
        let ndc_y = 1.0 - (y as f64 + 0.5) / f64::from(SIZE.1) * 2.0;
        let dir = view.forward
            + view.right * (ndc_x * view.tan_half_x)
            + view.up * (ndc_y * view.tan_half_y);
        eye + dir * (-eye.z / dir.z)
    };
    browser.hold_key("m", 50);
    let (a, b) = ((70, 60), (250, 190));
    for at in [a, b] {
        browser.click(at.0, at.1);
    }
    browser.wait_for(
        "two points measured",
        "const s = JSON.parse(document.getElementById('farfield').dataset.status || '{}'); \
         return !!s.measure && s.measure.points.length === 2",
        REPORT,
        WAIT,
    );
    let measured = status(&browser)["measure"]["distance"]
        .as_f64()
        .unwrap_or(f64::NAN);
    let truth = on_plane(a).distance(on_plane(b));
    eprintln!("measured {measured:.3} between two picked points; the true distance {truth:.3}");
    assert!(truth > 30.0, "the clicks are far apart: {truth}");
    assert!(
        ((measured - truth) / truth).abs() < 0.01,
        "measured {measured:.3}, true {truth:.3}"
    );
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}

/// The clipping box (`?clip=inside&clip_box=...`) draws what `farfield
/// render --clip inside --clip-box ...` draws, on WebGPU and WebGL2, and
/// hides what it should: kept to the upper half of the scene, the bunny's
/// lower half is gone from the picture.
#[test]
fn a_clipping_box_hides_what_is_outside_it() {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let Some((dir, bunny, web)) = setup("viewer-clip") else {
        return;
    };
    let rt = runtime();
    let server = rt.block_on(serve(&dir, &web, "127.0.0.1:0".parse().unwrap()));
    let browser = Browser::start(SIZE.0, SIZE.1);
    let camera = camera_of_fragment(START);
    let upper = [0.0, 0.0, 0.5, 1.0, 1.0, 1.0];
    let clip = farfield_render::Clip::from_corners(upper, farfield_render::Keep::Inside);
    let clipped = reference_with(&bunny, camera, SIZE, |job| job.clip = Some(clip)).unwrap();
    let plain = reference(&bunny, camera, SIZE.0, SIZE.1).unwrap();
    let lowest_lit_row = |rgba: &[u8]| {
        (0..SIZE.1)
            .rev()
            .find(|&y| {
                (0..SIZE.0).any(|x| {
                    let p = &rgba[((y * SIZE.0 + x) * 4) as usize..][..3];
                    p.iter().map(|&c| u32::from(c)).sum::<u32>() > 30
                })
            })
            .unwrap_or(0)
    };
    let (kept, all) = (lit(&clipped), lit(&plain));
    let (clipped_bottom, plain_bottom) = (lowest_lit_row(&clipped), lowest_lit_row(&plain));
    eprintln!(
        "headless: {kept} of {all} lit pixels kept; lowest lit row {clipped_bottom} against {plain_bottom}"
    );
    assert!(kept < all * 4 / 5 && kept > all / 10, "{kept} of {all}");
    assert!(
        clipped_bottom + 10 < plain_bottom,
        "{clipped_bottom} {plain_bottom}"
    );
    draws_like(
        &browser,
        &server,
        "clip=inside&clip_box=0,0,0.5,1,1,1",
        &clipped,
        &plain,
    );
    drop(browser);
    rt.block_on(server.shutdown()).unwrap();
}
