//! The interactive viewer, as people use it: in a native window under
//! Xvfb (`window`), and in headless Chromium over WebDriver (`browser`).
//!
//! Both compare what is on screen with `farfield render`'s headless image
//! of the same camera, so they fail if the viewer draws anything else.
//! Their tools (Xvfb, xdotool; chromium, chromedriver, the built web
//! assets) are required when `FARFIELD_REQUIRE_VIEWER_TOOLS=1`, which
//! `.ci/run` sets; elsewhere a missing tool skips the test, saying so.

mod browser;
mod webdriver;
mod window;

use std::path::{Path, PathBuf};

use farfield_builder::import::{Params, load_input};
use farfield_image::compare;
use farfield_render::headless_or_skip;
use farfield_store::write_atomic;
use farfield_tests::shared_data;
use farfield_view::camera_spec::CameraSpec;
use farfield_view::render_job::Source;

use crate::build;
use crate::streaming::job;

/// Set by `.ci/run`: a missing tool fails the viewer tests instead of skipping them.
const REQUIRE_ENV: &str = "FARFIELD_REQUIRE_VIEWER_TOOLS";

/// Fails (under [`REQUIRE_ENV`]) or skips (elsewhere) for a missing `what`.
fn missing(what: &str) {
    let required = std::env::var(REQUIRE_ENV).is_ok_and(|v| v.trim() == "1");
    assert!(!required, "{REQUIRE_ENV}=1 but {what}");
    eprintln!("SKIPPED: {what}");
}

/// Whether `program` runs (`--version`).
fn have(program: &str) -> bool {
    std::process::Command::new(program)
        .arg("--version")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// The bunny built into `dir/bunny.ff`, or `None` without the shared data.
fn bunny_in(dir: &Path) -> Option<PathBuf> {
    let data = shared_data()?;
    let scene = load_input(
        data.join("stanford-bunny.obj").to_str().unwrap(),
        &Params::default(),
    )
    .unwrap();
    let path = dir.join("bunny.ff");
    write_atomic(&path, &build(scene)).unwrap();
    Some(path)
}

/// `farfield render --file` of `file` at `camera`, `width` x `height`.
fn reference(file: &Path, camera: CameraSpec, width: u32, height: u32) -> Option<Vec<u8>> {
    let mut renderer = headless_or_skip(width, height).unwrap()?;
    let mut job = job(Source::File(file.to_owned()), camera);
    (job.width, job.height) = (width, height);
    let rendered = farfield_view::render_job::run(&job, &mut renderer, false).unwrap();
    assert!(rendered.report.refined);
    Some(rendered.rgba)
}

/// A link's camera (`eye=..&target=..&fov=..`) as a spec, read as the
/// viewer reads its address.
fn camera_of_fragment(fragment: &str) -> CameraSpec {
    farfield_viewer::link::parse_fragment(fragment)
        .unwrap_or_else(|e| panic!("camera {fragment:?}: {e}"))
        .unwrap_or_else(|| panic!("no camera in {fragment:?}"))
}

/// PSNR of `shown` against `reference` (RGB; alpha ignored).
fn psnr(reference: &[u8], shown: &[u8], width: u32, height: u32) -> f64 {
    compare(reference, shown, width, height, 8).unwrap().psnr_db
}

/// Pixels that are not the black background: a picture, not an empty frame.
fn lit(rgba: &[u8]) -> usize {
    rgba.chunks(4)
        .filter(|p| p[..3].iter().any(|&c| c > 16))
        .count()
}
