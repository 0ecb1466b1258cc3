//! The open-files limit, raised at start-up to what the connection limit
//! needs: every connection is a file descriptor, and the usual soft limit
//! (1024) would otherwise let about a thousand idle sockets deny service.

/// Descriptors kept for everything but client sockets: scene files, the
/// listener, the runtime, logs.
pub const RESERVED_FILES: u64 = 256;

/// How `files` descriptors are shared out: [`RESERVED_FILES`] for the
/// server's own, then connections and refusals being answered, as many as
/// `limits` asks for where they fit, else a fifth of what is left for
/// refusals (at least one) and the rest for connections (at least one).
pub fn share_open_files(files: u64, limits: &crate::limits::Limits) -> (usize, usize) {
    let spare = usize::try_from(files.saturating_sub(RESERVED_FILES)).unwrap_or(usize::MAX);
    if spare >= limits.max_connections.saturating_add(limits.max_refusing) {
        return (limits.max_connections, limits.max_refusing);
    }
    let refusing = (spare / 5).clamp(1, limits.max_refusing.max(1));
    let connections = spare
        .saturating_sub(refusing)
        .clamp(1, limits.max_connections.max(1));
    (connections, refusing)
}

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

    /// Under `ulimit -n 400` the server once served 144 connections and
    /// answered up to 256 refusals besides, with 256 descriptors kept for
    /// itself: 656 in all, and accept and rescan failed. Now every
    /// descriptor is counted once.
    #[test]
    fn connections_and_refusals_fit_in_the_limit_with_the_reserve() {
        let limits = crate::limits::Limits::default();
        for files in [300, 400, 1024, 4096] {
            let (connections, refusing) = share_open_files(files, &limits);
            assert!(connections >= 1 && refusing >= 1, "{files}");
            assert!(
                (connections + refusing) as u64 + RESERVED_FILES <= files.max(RESERVED_FILES + 2),
                "{files}: {connections} + {refusing}"
            );
        }
        assert_eq!(share_open_files(400, &limits), (116, 28));
        let plenty = share_open_files(1 << 20, &limits);
        assert_eq!(plenty, (limits.max_connections, limits.max_refusing));
    }

    #[cfg(unix)]
    #[test]
    fn the_limit_never_goes_down() {
        let now = raise_open_files(0).expect("a limit");
        assert!(now >= 1, "{now}");
        assert_eq!(raise_open_files(1), Some(now), "asking for less keeps it");
    }
}
