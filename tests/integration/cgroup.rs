//! A memory cgroup made by a test, to run a child process under a memory
//! limit (cgroup v1's memory controller, or v2's), removed when dropped.
//!
//! Making one needs permission (root, or a delegated subtree). Where it is
//! refused the test says it was skipped and passes, as tests on the shared
//! data do; `FARFIELD_REQUIRE_CGROUP=1` (set by `.ci/run` when it runs as
//! root) turns that into a failure, so CI cannot go green without them.

use std::path::{Path, PathBuf};

#[derive(Debug)]
pub(crate) struct MemoryCgroup {
    dir: PathBuf,
    v2: bool,
}

/// This process's path in the memory hierarchy, from `/proc/self/cgroup`:
/// v1's `memory` line, or v2's `0::` line.
fn own_path(v2: bool) -> Option<String> {
    let text = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    text.lines().find_map(|l| {
        let mut parts = l.splitn(3, ':');
        let (id, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        let ours = if v2 {
            id == "0" && controllers.is_empty()
        } else {
            controllers.split(',').any(|c| c == "memory")
        };
        ours.then(|| path.to_owned())
    })
}

impl MemoryCgroup {
    /// A fresh cgroup limited to `limit` bytes (swap included where the
    /// kernel counts it), or `None` after saying why the test is skipped.
    pub(crate) fn create(name: &str, limit: u64) -> Option<Self> {
        match Self::try_create(name, limit) {
            Ok(c) => Some(c),
            Err(why) => {
                if std::env::var_os("FARFIELD_REQUIRE_CGROUP").is_some_and(|v| v == "1") {
                    panic!("FARFIELD_REQUIRE_CGROUP=1 but no memory cgroup could be made: {why}");
                }
                eprintln!(
                    "SKIPPED: no memory cgroup could be made ({why}); run as root to run this test"
                );
                None
            }
        }
    }

    fn try_create(name: &str, limit: u64) -> Result<Self, String> {
        let leaf = format!("farfield-test-{}-{name}", std::process::id());
        let v1_root = Path::new("/sys/fs/cgroup/memory");
        if v1_root.join("memory.limit_in_bytes").exists() || v1_root.join("cgroup.procs").exists() {
            let own = own_path(false).ok_or("no memory line in /proc/self/cgroup")?;
            let dir = v1_root.join(own.trim_start_matches('/')).join(leaf);
            std::fs::create_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
            let made = Self { dir, v2: false };
            made.write("memory.limit_in_bytes", limit)?;
            // Swap would let the process outgrow the limit unseen.
            if made.dir.join("memory.memsw.limit_in_bytes").exists() {
                made.write("memory.memsw.limit_in_bytes", limit)?;
            }
            return Ok(made);
        }
        let v2_root = Path::new("/sys/fs/cgroup");
        let controllers = std::fs::read_to_string(v2_root.join("cgroup.controllers"))
            .map_err(|e| format!("neither cgroup v1's memory controller nor cgroup v2: {e}"))?;
        if !controllers.split_whitespace().any(|c| c == "memory") {
            return Err("cgroup v2 without the memory controller".into());
        }
        let own = own_path(true).ok_or("no v2 line in /proc/self/cgroup")?;
        let parent = v2_root.join(own.trim_start_matches('/'));
        // The child may only have the controller if its parent hands it down.
        let _ = std::fs::write(parent.join("cgroup.subtree_control"), "+memory");
        let dir = parent.join(leaf);
        std::fs::create_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let made = Self { dir, v2: true };
        made.write("memory.max", limit)?;
        if made.dir.join("memory.swap.max").exists() {
            made.write("memory.swap.max", 0)?;
        }
        Ok(made)
    }

    fn write(&self, file: &str, value: u64) -> Result<(), String> {
        let path = self.dir.join(file);
        std::fs::write(&path, value.to_string()).map_err(|e| format!("{}: {e}", path.display()))
    }

    fn read(&self, file: &str) -> Option<String> {
        std::fs::read_to_string(self.dir.join(file)).ok()
    }

    /// Moves process `pid` into the cgroup.
    pub(crate) fn add(&self, pid: u32) {
        self.write("cgroup.procs", u64::from(pid))
            .expect("moving the process into the cgroup");
    }

    /// The limit as the kernel holds it.
    pub(crate) fn limit(&self) -> u64 {
        let file = if self.v2 {
            "memory.max"
        } else {
            "memory.limit_in_bytes"
        };
        self.read(file)
            .and_then(|t| t.trim().parse().ok())
            .expect("the cgroup's limit")
    }

    /// The most memory the cgroup's processes held at once, where the
    /// kernel tells (v1; v2 from 5.19).
    pub(crate) fn peak(&self) -> Option<u64> {
        let file = if self.v2 {
            "memory.peak"
        } else {
            "memory.max_usage_in_bytes"
        };
        self.read(file)?.trim().parse().ok()
    }

    /// Processes the kernel killed for want of memory in the cgroup.
    pub(crate) fn oom_kills(&self) -> u64 {
        let file = if self.v2 {
            "memory.events"
        } else {
            "memory.oom_control"
        };
        self.read(file)
            .and_then(|t| {
                t.lines()
                    .find_map(|l| l.strip_prefix("oom_kill ")?.trim().parse().ok())
            })
            .unwrap_or(0)
    }
}

impl Drop for MemoryCgroup {
    /// Removes the cgroup once its processes are gone (the caller kills
    /// them first: drop the child before the cgroup).
    fn drop(&mut self) {
        for _ in 0..50 {
            if std::fs::remove_dir(&self.dir).is_ok() {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
        eprintln!("could not remove {}", self.dir.display());
    }
}
