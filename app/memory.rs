//! How much host memory a request may use: what the machine has available (Linux `MemAvailable`, capped by a
//! cgroup v2 limit when the process runs under one) and byte sizes written for people.
//!
//! Large requests are checked against this *before* anything is allocated. On Linux an impossible allocation
//! usually does not fail: it succeeds lazily and the kernel's OOM killer ends the process later, which is the
//! abort a user cannot catch. Estimating first is the only way to turn that into a message.

/// Bytes the process can still allocate without pushing the machine into swap or out-of-memory, or `None`
/// where the platform does not say (then no memory check is made).
pub fn available() -> Option<u64> {
    #[cfg(target_os = "linux")]
    {
        let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
        let available = meminfo
            .lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map(|kib| kib * 1024)?;
        Some(match cgroup_headroom() {
            Some(c) => available.min(c),
            None => available,
        })
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// The budget a request gets when the user sets none: four fifths of [`available`], leaving the rest for the
/// loaded mesh, the process itself and the machine's other work.
pub fn default_budget() -> Option<u64> {
    available().map(|a| a / 5 * 4)
}

/// Headroom under the cgroup v2 memory limit (containers, Slurm jobs), if the process has one.
#[cfg(target_os = "linux")]
fn cgroup_headroom() -> Option<u64> {
    let cgroup = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = cgroup.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok().and_then(|s| s.trim().parse::<u64>().ok());
    // "max" (no limit) does not parse as a number.
    let limit = read("memory.max")?;
    Some(limit.saturating_sub(read("memory.current").unwrap_or(0)))
}

/// Parses a size as people write it: `512M`, `8G`, `1.5GiB`, `1000000` (bytes).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number.parse().map_err(|_| format!("'{s}' is not a size (examples: 512M, 8G)"))?;
    let scale: u64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        "t" | "tb" | "tib" => 1 << 40,
        _ => return Err(format!("'{s}': unknown unit '{unit}' (use K, M, G or T)")),
    };
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("'{s}' is not a usable size"));
    }
    Ok(bytes as u64)
}

/// `1.5 GiB`, `640 MiB`, `12 KiB`, `100 bytes`.
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 { format!("{bytes} bytes") } else { format!("{value:.1} {}", UNITS[unit]) }
}

/// The process's peak resident memory since it started or since [`reset_peak`] (Linux `VmHWM`), where known.
pub fn peak_resident() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?.trim().trim_end_matches("kB").trim();
    kib.parse::<u64>().ok().map(|k| k * 1024)
}

/// Restarts [`peak_resident`] from the current resident size (Linux: `5` into `/proc/self/clear_refs`);
/// `false` where that is not possible.
pub fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}
