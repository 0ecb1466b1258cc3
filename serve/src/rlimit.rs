//! The open-files limit, raised at start-up to what the connection limit
//! needs: every connection is a file descriptor, and the usual soft limit
//! (1024) would otherwise let about a thousand idle sockets deny service.

/// Descriptors kept for everything but client sockets: scene files, the
/// listener, the runtime, logs.
pub const RESERVED_FILES: u64 = 256;

/// Raises the soft limit on open files towards `wanted` (never past the
/// hard limit, never lowering it) and returns the soft limit now in force,
/// or `None` where the platform has no such limit.
pub fn raise_open_files(wanted: u64) -> Option<u64> {
    #[cfg(unix)]
    {
        let mut limit = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: `limit` is a valid, writable rlimit for the call to fill.
        if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) } != 0 {
            return None;
        }
        let target = (wanted as libc::rlim_t).min(limit.rlim_max);
        if target > limit.rlim_cur {
            let raised = libc::rlimit {
                rlim_cur: target,
                rlim_max: limit.rlim_max,
            };
            // SAFETY: `raised` is a valid rlimit; the call only reads it.
            if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } == 0 {
                limit.rlim_cur = target;
            }
        }
        // `rlim_t` is u64 on Linux, not on every Unix.
        #[allow(clippy::unnecessary_cast)]
        Some(limit.rlim_cur as u64)
    }
    #[cfg(not(unix))]
    {
        let _ = wanted;
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn the_limit_never_goes_down() {
        let now = raise_open_files(0).expect("a limit");
        assert!(now >= 1, "{now}");
        assert_eq!(raise_open_files(1), Some(now), "asking for less keeps it");
    }
}
