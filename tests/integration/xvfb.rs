//! A private X server for tests that open windows.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// An Xvfb server on a free display, killed when dropped.
pub(crate) struct Xvfb {
    child: Child,
    display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        // SIGTERM, so Xvfb removes its lock file (a SIGKILL leaves
        // /tmp/.X<n>-lock behind, and that display cannot be used again).
        let asked = Command::new("kill")
            .arg(self.child.id().to_string())
            .status()
            .is_ok_and(|s| s.success());
        if !asked {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

/// Starts Xvfb on the first free display from :90 (no socket and no lock
/// file), waiting for its socket.
pub(crate) fn start_xvfb() -> Option<Xvfb> {
    for n in 90..190 {
        let socket = format!("/tmp/.X11-unix/X{n}");
        let lock = format!("/tmp/.X{n}-lock");
        if std::path::Path::new(&socket).exists() || std::path::Path::new(&lock).exists() {
            continue;
        }
        let display = format!(":{n}");
        let child = Command::new("Xvfb")
            .args([
                display.as_str(),
                "-screen",
                "0",
                "640x480x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .ok()?;
        let xvfb = Xvfb { child, display };
        let started = Instant::now();
        while started.elapsed() < Duration::from_secs(10) {
            if std::path::Path::new(&socket).exists() {
                return Some(xvfb);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    None
}

impl Xvfb {
    /// The display's name, for `DISPLAY`.
    pub(crate) fn display(&self) -> &str {
        &self.display
    }
}
