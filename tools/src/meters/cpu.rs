//! What the machine gave a benchmark: the process's CPU time, and the
//! share of the machine's CPU time that the hypervisor took away ("steal").
//!
//! Build benchmarks run on shared virtual machines whose speed swings by
//! tens of percent from one hour to the next. Reported beside a throughput,
//! these two figures tell a slow build from a slow machine: a build that
//! kept fewer threads busy, or ran while the host stole time, is not the
//! same measurement as one that had both cores.
//!
//! Linux-only by nature (`/proc/stat`, `getrusage`); elsewhere the figures
//! are reported as absent rather than guessed.

use std::time::Instant;

/// A reading of the clocks, taken before and after what is measured.
#[derive(Debug, Clone, Copy)]
pub struct CpuClock {
    wall: Instant,
    process_seconds: Option<f64>,
    host: Option<HostTicks>,
}

/// What the machine gave between two readings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpuUse {
    /// Process CPU seconds (user and system, all threads) per wall second:
    /// 2.0 means two threads busy all the time.
    pub busy_threads: Option<f64>,
    /// Steal ticks over all ticks of all the machine's CPUs (in a virtual
    /// machine, its virtual CPUs): the share of the machine's time the
    /// hypervisor gave to someone else. Idle CPUs count in the total, so
    /// on a machine with more CPUs than the build keeps busy, steal from
    /// the busy ones is diluted.
    pub steal_fraction: Option<f64>,
}

impl CpuClock {
    pub fn now() -> Self {
        Self {
            wall: Instant::now(),
            process_seconds: process_cpu_seconds(),
            host: std::fs::read_to_string("/proc/stat")
                .ok()
                .and_then(|s| HostTicks::parse(&s)),
        }
    }

    /// The machine's use from `self` to `later`.
    pub fn until(&self, later: &CpuClock) -> CpuUse {
        let wall = later.wall.duration_since(self.wall).as_secs_f64();
        let busy_threads = self
            .process_seconds
            .zip(later.process_seconds)
            .filter(|_| wall > 0.0)
            .map(|(a, b)| (b - a) / wall);
        let steal_fraction = self.host.zip(later.host).and_then(|(a, b)| {
            let total = b.total.checked_sub(a.total)?;
            let steal = b.steal.checked_sub(a.steal)?;
            (total > 0).then(|| steal as f64 / total as f64)
        });
        CpuUse {
            busy_threads,
            steal_fraction,
        }
    }
}

/// The all-CPU line of `/proc/stat`, summed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct HostTicks {
    /// user, nice, system, idle, iowait, irq, softirq and steal (guest time
    /// is already counted in user).
    total: u64,
    steal: u64,
}

impl HostTicks {
    fn parse(stat: &str) -> Option<Self> {
        let line = stat.lines().find(|l| l.starts_with("cpu "))?;
        let ticks: Vec<u64> = line
            .split_whitespace()
            .skip(1)
            .take(8)
            .map(|t| t.parse().ok())
            .collect::<Option<_>>()?;
        // Kernels older than 2.6.11 have no steal column: no figure then.
        (ticks.len() == 8).then(|| Self {
            // Counters only grow, but a corrupt line must not overflow.
            total: ticks.iter().fold(0u64, |sum, &t| sum.wrapping_add(t)),
            steal: ticks[7],
        })
    }
}

#[cfg(target_os = "linux")]
fn process_cpu_seconds() -> Option<f64> {
    // SAFETY: `rusage` is plain old data, for which all zeros is a value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `getrusage` only writes the struct it is given.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return None;
    }
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    Some(seconds(usage.ru_utime) + seconds(usage.ru_stime))
}

#[cfg(not(target_os = "linux"))]
fn process_cpu_seconds() -> Option<f64> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steal_is_the_eighth_column_of_the_all_cpu_line() {
        let stat = "cpu  100 5 20 800 10 1 2 62 7 0\ncpu0 50 2 10 400 5 0 1 31 0 0\n";
        assert_eq!(
            HostTicks::parse(stat),
            Some(HostTicks {
                total: 100 + 5 + 20 + 800 + 10 + 1 + 2 + 62,
                steal: 62
            })
        );
        assert_eq!(HostTicks::parse("cpu  1 2 3 4\n"), None);
        assert_eq!(HostTicks::parse("intr 5\n"), None);
    }

    #[test]
    fn steal_fraction_is_steal_over_all_ticks_between_readings() {
        let at = |total, steal, process| CpuClock {
            wall: Instant::now(),
            process_seconds: Some(process),
            host: Some(HostTicks { total, steal }),
        };
        let before = at(1000, 10, 1.0);
        let after = at(1400, 110, 1.0);
        assert_eq!(before.until(&after).steal_fraction, Some(0.25));
        // A counter that went backwards (another reading's) gives nothing.
        assert_eq!(after.until(&before).steal_fraction, None);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_busy_thread_counts_as_about_one() {
        let before = CpuClock::now();
        let mut x = 1u64;
        while before.wall.elapsed().as_millis() < 200 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let busy = before.until(&CpuClock::now()).busy_threads.unwrap();
        // This thread spinning, maybe descheduled for a while on a loaded
        // machine; other tests' threads may add to it, up to every CPU.
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        assert!(
            (0.3..cpus as f64 + 0.5).contains(&busy),
            "busy threads {busy} on {cpus} CPUs"
        );
    }
}
