//! A private X server for tests that open windows.

use std::process::{Child, Command, Stdio};
use std::time::Duration;

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

/// Starts Xvfb on a free display of its own choosing (`-displayfd`: it
/// writes the display's number once it accepts connections). Choosing here
/// by looking for a free lock file raced: two tests in parallel took the
/// same display, and the first to finish killed the other's X server.
pub(crate) fn start_xvfb() -> Option<Xvfb> {
    use std::io::{BufRead, BufReader};
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "640x480x24",
            "-nolisten",
            "tcp",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .ok()?;
    let stdout = child.stdout.take()?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut reader = BufReader::new(stdout);
        let mut line = String::new();
        let _ = reader.read_line(&mut line);
        let _ = tx.send(line);
        // Read on to the end, so the server never writes into a closed pipe.
        let _ = std::io::copy(&mut reader, &mut std::io::sink());
    });
    let number = rx
        .recv_timeout(Duration::from_secs(10))
        .ok()
        .and_then(|line| line.trim().parse::<u32>().ok());
    let xvfb = Xvfb {
        child,
        display: format!(":{}", number.unwrap_or(0)),
    };
    // Dropped without a display: the server is stopped.
    number.map(|_| xvfb)
}

impl Xvfb {
    /// The display's name, for `DISPLAY`.
    pub(crate) fn display(&self) -> &str {
        &self.display
    }
}
