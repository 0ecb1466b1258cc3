//! Network namespaces, made and removed with iproute2's `ip` (as a person
//! setting up a test network by hand would), and entered by a thread.

use std::process::Command;

use anyhow::{Context, bail};

/// Runs `ip ARGS`, failing with what it printed.
pub fn ip(args: &[&str]) -> anyhow::Result<()> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .context("running `ip` (iproute2)")?;
    if !out.status.success() {
        bail!(
            "`ip {}` failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

/// Whether namespace `name` exists.
pub fn exists(name: &str) -> bool {
    std::path::Path::new("/run/netns").join(name).exists()
}

/// Runs `f` on a new thread inside namespace `name`; what `f` makes
/// there (sockets, and threads it starts, which inherit the namespace)
/// belongs to it.
pub fn run_in<T: Send + 'static>(
    name: &str,
    f: impl FnOnce() -> T + Send + 'static,
) -> anyhow::Result<T> {
    let path = std::path::Path::new("/run/netns").join(name);
    let ns = std::fs::File::open(&path)
        .with_context(|| format!("opening network namespace {}", path.display()))?;
    std::thread::spawn(move || {
        use std::os::fd::AsRawFd;
        // SAFETY: `ns` is an open namespace file; setns changes only this thread.
        if unsafe { libc::setns(ns.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
            return Err(std::io::Error::last_os_error()).context("entering the namespace");
        }
        Ok(f())
    })
    .join()
    .map_err(|_| anyhow::anyhow!("the thread inside namespace {name} panicked"))?
}
