//! The memory a build may use: `--memory` as written (`4G`, `512MiB`,
//! `1000000`), and the default, a share of what this machine, or the
//! memory cgroup the build runs in, has.

/// The share of the machine's (or cgroup's) memory a build takes by
/// default: the rest is for the page cache that the temporary files and the
/// inputs stream through, and for whatever else runs.
const DEFAULT_SHARE: f64 = 0.5;

/// Parses a size in bytes: a number with an optional binary unit (K, M, G,
/// T; `KiB`, `KB` and `k` alike, all powers of 1024).
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let number: f64 = number
        .parse()
        .map_err(|_| format!("{text:?} is not a size (write 4G, 512M or a number of bytes)"))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => return Err(format!("{text:?}: unknown unit {other:?} (K, M, G or T)")),
    };
    let bytes = number * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 0.0 && bytes < u64::MAX as f64) {
        return Err(format!("{text:?} is out of range"));
    }
    Ok(bytes as u64)
}

/// The default budget: half of the smaller of the machine's memory and the
/// limit of the memory cgroup this process is in (v1 or v2); 4 GiB where
/// neither can be read.
pub fn default_memory() -> u64 {
    let total = machine_memory().into_iter().chain(cgroup_limit()).min();
    total.map_or(4 << 30, |t| (t as f64 * DEFAULT_SHARE) as u64)
}

/// `MemTotal` of /proc/meminfo, in bytes.
fn machine_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The memory limit of this process's cgroup, when it has one.
fn cgroup_limit() -> Option<u64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    for line in groups.lines() {
        let mut parts = line.splitn(3, ':');
        let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        let file = if controllers.split(',').any(|c| c == "memory") {
            format!("/sys/fs/cgroup/memory{path}/memory.limit_in_bytes")
        } else if controllers.is_empty() {
            format!("/sys/fs/cgroup{path}/memory.max")
        } else {
            continue;
        };
        // "max" (v2) or a huge number (v1) means no limit.
        if let Some(limit) = std::fs::read_to_string(file)
            .ok()
            .and_then(|t| t.trim().parse::<u64>().ok())
            .filter(|&l| l < 1 << 60)
        {
            return Some(limit);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units_and_bad_ones_are_refused() {
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert_eq!(parse_bytes("4G"), Ok(4 << 30));
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5k"), Ok(1536));
        assert_eq!(parse_bytes(" 2 gb "), Ok(2 << 30));
        for bad in ["", "G", "4X", "-1", "1e400", "4 G B"] {
            assert!(parse_bytes(bad).is_err(), "{bad:?} accepted");
        }
        assert!(default_memory() > 0);
    }
}
