//! Opening the GPU adapter on a headless machine: no spurious errors.

use std::process::Output;

use farfield_tests::{child_ran, child_test};

use farfield_render::{DEVICE_SELECT_OFF, headless_or_skip};

/// Tells [`open_adapter_child`] that it runs as the child.
const CHILD_ENV: &str = "FARFIELD_ADAPTER_CHILD";

/// Re-runs this test binary on [`open_adapter_child`] with no desktop
/// session in the environment, with or without the device-select switch.
fn open_adapter_in_child(switch_off_device_select: bool) -> Output {
    let mut command = child_test("adapter::open_adapter_child");
    command
        .env(CHILD_ENV, "1")
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .env_remove(DEVICE_SELECT_OFF.0);
    if switch_off_device_select {
        command.env(DEVICE_SELECT_OFF.0, DEVICE_SELECT_OFF.1);
    }
    let output = command.output().expect("spawn");
    assert!(
        output.status.success(),
        "child failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        child_ran(&output.stdout),
        "the child test did not run: {}",
        String::from_utf8_lossy(&output.stdout)
    );
    output
}

/// `farfield` sets [`DEVICE_SELECT_OFF`] first thing on a headless machine
/// (`quiet_device_select_when_headless`); with it, opening the adapter
/// prints no libwayland error. Without it, on machines with Mesa's
/// device-select layer (lavapipe's package installs it), the error appears:
/// the test says whether this machine shows the difference.
#[test]
fn a_headless_machine_opens_the_adapter_without_a_wayland_error() {
    let message = "XDG_RUNTIME_DIR";
    let quiet = open_adapter_in_child(true);
    let stderr = String::from_utf8_lossy(&quiet.stderr);
    assert!(!stderr.contains(message), "with the switch: {stderr}");
    let noisy = open_adapter_in_child(false);
    let shown = String::from_utf8_lossy(&noisy.stderr).contains(message);
    eprintln!(
        "without {}: libwayland's error {}",
        DEVICE_SELECT_OFF.0,
        if shown {
            "appears (the switch is what silences it)"
        } else {
            "does not appear on this machine (no device-select layer)"
        }
    );
}

/// The child's work: open a headless adapter. Does nothing unless started
/// by the test above.
#[test]
#[ignore = "subprocess entry point: run by its parent test"]
fn open_adapter_child() {
    if std::env::var_os(CHILD_ENV).is_none() {
        return;
    }
    let renderer = headless_or_skip(8, 8).expect("adapter");
    drop(renderer);
}
