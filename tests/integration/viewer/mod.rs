//! The interactive viewer, as people use it: in a native window under
//! Xvfb (`window`), and in headless Chromium over WebDriver (`browser`).
//!
//! Both compare what is on screen with `farfield render`'s headless image
//! of the same camera, so they fail if the viewer draws anything else.
//! Their tools (Xvfb, xdotool; chromium, chromedriver, the built web
//! assets) are required when `FARFIELD_REQUIRE_VIEWER_TOOLS=1`, which
//! `.ci/run` sets; elsewhere a missing tool skips the test, saying so.

mod browser;
mod first_command;
mod webdriver;
mod window;

use std::path::{Path, PathBuf};

use farfield_builder::import::{Params, load_input};
use farfield_builder::plp::PlpOptions;
use farfield_client::budget::BudgetSpec;
use farfield_client::camera_spec::CameraSpec;
use farfield_client::render_job::Source;
use farfield_image::compare;
use farfield_render::headless_or_skip;
use farfield_store::write_atomic;
use farfield_tests::shared_data;
use farfield_traverse::Budget;

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
    reference_on_budget(file, camera, (width, height), BudgetSpec::default())
}

/// The same with a PLP budget (`farfield render --budget`).
fn reference_on_budget(
    file: &Path,
    camera: CameraSpec,
    size: (u32, u32),
    budget: BudgetSpec,
) -> Option<Vec<u8>> {
    reference_with(file, camera, size, |job| job.budget = budget)
}

/// The same with the job as `change` leaves it (`farfield render`'s
/// options).
fn reference_with(
    file: &Path,
    camera: CameraSpec,
    (width, height): (u32, u32),
    change: impl FnOnce(&mut farfield_client::render_job::RenderJob),
) -> Option<Vec<u8>> {
    let mut renderer = headless_or_skip(width, height).unwrap()?;
    let mut job = job(Source::File(file.to_owned()), camera);
    (job.width, job.height) = (width, height);
    change(&mut job);
    let rendered = farfield_client::render_job::run(&job, &mut renderer, false).unwrap();
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

/// The PLP scene of the viewer tests: rows of boxes (`crate::plp::rows`)
/// built into a folder, a camera in front of them, and `farfield render`'s
/// images of that camera at a 2 % budget and whole.
struct PlpRows {
    file: PathBuf,
    /// The camera, as a link's fragment.
    start: &'static str,
    camera: CameraSpec,
    budgeted: Vec<u8>,
    whole: Vec<u8>,
}

impl PlpRows {
    /// The budget the viewers are given, in percent.
    const PERCENT: f64 = 2.0;

    /// Builds it into `dir`; `None` without a headless adapter.
    fn build(dir: &Path, size: (u32, u32)) -> Option<Self> {
        let file = dir.join("rows.ff");
        let built = crate::plp::build(&crate::plp::rows(), &PlpOptions::default());
        write_atomic(&file, &built).unwrap();
        let start = "eye=8,-6,1&target=8,8,1&fov=60";
        let camera = camera_of_fragment(start);
        let budget = BudgetSpec {
            triangles: Budget::Percent(Self::PERCENT),
            ms: None,
            mode: None,
        };
        let budgeted = reference_on_budget(&file, camera, size, budget)?;
        let whole = reference(&file, camera, size.0, size.1)?;
        // The budget must show in the picture for a test to say anything.
        let apart = compare(&whole, &budgeted, size.0, size.1, 8)
            .unwrap()
            .wrong_fraction;
        assert!(
            apart > 0.01,
            "2 % looks like the whole scene: {apart} wrong"
        );
        Some(Self {
            file,
            start,
            camera,
            budgeted,
            whole,
        })
    }

    /// Checks that `shown` is the budgeted image (and says how far it is
    /// from the whole one).
    fn check(&self, shown: &[u8], size: (u32, u32), what: &str) {
        let db = psnr(&self.budgeted, shown, size.0, size.1);
        let against_whole = psnr(&self.whole, shown, size.0, size.1);
        eprintln!(
            "{what}: {db:.1} dB against render --budget 2%, {against_whole:.1} dB against the whole scene"
        );
        assert!(lit(shown) > 1000, "{what}: the boxes are shown");
        assert!(
            db >= 30.0,
            "{what}: differs from render --budget 2%: {db:.1} dB"
        );
    }
}
