//! Helpers shared by farfield's integration tests.
//!
//! [`shared_data`] finds the real scans in `../shared/data` (or wherever
//! `FARFIELD_DATA` points). A user's clone has no such folder: tests that
//! need it print that they were skipped and pass. CI sets
//! `FARFIELD_REQUIRE_DATA=1`, which turns a missing folder into a failure,
//! so CI can never go green without having run them.

use std::path::PathBuf;

/// The folder of shared test data, or `None` (after printing why) when it
/// is absent and not required.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("FARFIELD_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    if dir.join("stanford-bunny.obj").is_file() {
        return Some(dir);
    }
    if std::env::var_os("FARFIELD_REQUIRE_DATA").is_some_and(|v| v == "1") {
        panic!(
            "FARFIELD_REQUIRE_DATA=1 but the shared data is not at {}",
            dir.display()
        );
    }
    eprintln!(
        "SKIPPED: shared test data not found at {} (set FARFIELD_DATA to run these tests)",
        dir.display()
    );
    None
}

/// A fresh, empty scratch folder for one test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("farfield-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch folder");
    dir
}

/// This test binary again, on the one ignored test `name`: a subprocess
/// entry point, for tests that need a process of their own (a window, a
/// display, a resource limit, a signal, an environment). Entry points are
/// marked `#[ignore = "subprocess entry point: run by its parent test"]`:
/// half of a test is not a test, and in a normal run one would pass at once
/// with nothing to do, so they are not counted among the passing ones.
/// See [`child_ran`] for checking that it ran.
pub fn child_test(name: &str) -> std::process::Command {
    let mut command = std::process::Command::new(std::env::current_exe().expect("test binary"));
    command.args(child_test_args(name));
    command
}

/// The arguments that make a test binary run only its ignored test `name`,
/// for a caller that starts the binary another way (inside a network
/// namespace, say).
pub fn child_test_args(name: &str) -> [&str; 4] {
    [name, "--exact", "--ignored", "--nocapture"]
}

/// Whether a [`child_test`]'s output shows its entry point ran and passed:
/// a filter that matched nothing also exits with success.
pub fn child_ran(stdout: &[u8]) -> bool {
    String::from_utf8_lossy(stdout)
        .lines()
        .any(|l| l.starts_with("test result: ok. 1 passed"))
}
