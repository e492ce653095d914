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

/// Buffers at least this large are mapped apart, where huge pages can back them (one is 2 MiB on x86-64).
#[cfg(target_os = "linux")]
const MAPPED_FROM: usize = 4 << 20;

/// A zeroed buffer of `len` values, on Linux mapped apart and offered to the kernel for transparent huge pages
/// when large: a distance field's values (51 MB for Spot's band at 512) are written once, page by page, by every
/// thread, and taken 4 KiB at a time their first touch cost more page faults than any other step of the field (a
/// tenth of its time; the kernel zeroes a huge page in one fault). Where the kernel gives none, or elsewhere, the
/// pages are the allocator's. Reads as a slice.
pub struct Pages<T: bytemuck::Pod> {
    store: Store<T>,
}

enum Store<T> {
    Heap(Vec<T>),
    #[cfg(target_os = "linux")]
    Mapped(memmap2::MmapMut, usize),
}

impl<T: bytemuck::Pod> Pages<T> {
    /// `len` zeroed values.
    pub fn zeroed(len: usize) -> Pages<T> {
        #[cfg(target_os = "linux")]
        if let Some(bytes) = len.checked_mul(std::mem::size_of::<T>())
            && bytes >= MAPPED_FROM
            && let Ok(map) = memmap2::MmapOptions::new().len(bytes).map_anon()
        {
            // Only advice: without huge pages the mapping's 4 KiB pages serve as the allocator's would.
            let _ = map.advise(memmap2::Advice::HugePage);
            return Pages { store: Store::Mapped(map, len) };
        }
        Pages { store: Store::Heap(bytemuck::zeroed_vec(len)) }
    }
}

impl<T: bytemuck::Pod> Default for Pages<T> {
    fn default() -> Pages<T> {
        Pages { store: Store::Heap(Vec::new()) }
    }
}

impl<T: bytemuck::Pod> From<Vec<T>> for Pages<T> {
    fn from(values: Vec<T>) -> Pages<T> {
        Pages { store: Store::Heap(values) }
    }
}

impl<T: bytemuck::Pod> std::ops::Deref for Pages<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.store {
            Store::Heap(v) => v,
            // The mapping is page-aligned and exactly `len` values long.
            #[cfg(target_os = "linux")]
            Store::Mapped(map, len) => &bytemuck::cast_slice(&map[..])[..*len],
        }
    }
}

impl<T: bytemuck::Pod> std::ops::DerefMut for Pages<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        match &mut self.store {
            Store::Heap(v) => v,
            #[cfg(target_os = "linux")]
            Store::Mapped(map, len) => &mut bytemuck::cast_slice_mut(&mut map[..])[..*len],
        }
    }
}

impl<T: bytemuck::Pod> Clone for Pages<T> {
    fn clone(&self) -> Pages<T> {
        let mut copy = Pages::zeroed(self.len());
        copy.copy_from_slice(self);
        copy
    }
}

impl<T: bytemuck::Pod + PartialEq> PartialEq for Pages<T> {
    fn eq(&self, other: &Pages<T>) -> bool {
        self[..] == other[..]
    }
}

impl<T: bytemuck::Pod + std::fmt::Debug> std::fmt::Debug for Pages<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self[..].fmt(f)
    }
}

impl<'a, T: bytemuck::Pod> IntoIterator for &'a Pages<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> std::slice::Iter<'a, T> {
        self.iter()
    }
}
