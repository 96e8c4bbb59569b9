//! What a job asks of the machine: worker pools, physical memory, free disk, and the
//! sizes it reports ("354.0 MB").

use crate::render::StreamingMemory;
use anyhow::{anyhow, ensure};
use std::path::Path;

/// "354.0 MB" style sizes (decimal units).
pub fn human_bytes(b: u64) -> String {
    let b = b as f64;
    if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else if b >= 1e3 {
        format!("{:.1} kB", b / 1e3)
    } else {
        format!("{b} B")
    }
}

/// Physical memory in bytes (from /proc/meminfo), if known.
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Runs `f` on a rayon pool of `threads` threads (all cores when `None`).
pub fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        ensure!(n >= 1, "--threads must be at least 1");
        b = b.num_threads(n);
    }
    // The build error already names its cause: no context chain (it would repeat it).
    let pool = b
        .build()
        .map_err(|e| anyhow!("cannot start the worker threads: {e}"))?;
    Ok(pool.install(f))
}

/// The number of worker threads [`with_threads`] will start for `threads`: rayon's
/// default (`RAYON_NUM_THREADS`, else the available cores) when `None`. Asking rayon
/// itself would start its global pool just to count it.
pub fn pool_size(threads: Option<usize>) -> usize {
    threads.unwrap_or_else(|| {
        std::env::var("RAYON_NUM_THREADS")
            .ok()
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
    })
}

/// Total size of a file or of the files in a directory.
pub fn disk_size(path: &Path) -> u64 {
    if path.is_dir() {
        std::fs::read_dir(path)
            .map(|it| it.flatten().map(|e| disk_size(&e.path())).sum())
            .unwrap_or(0)
    } else {
        std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)
    }
}

/// "1.2 GB (2 threads x 600 MB per row + 5 MB of per-pixel images)".
pub fn describe_memory(m: &StreamingMemory) -> String {
    format!(
        "{} ({} thread{} x {} per row + {} of per-pixel images)",
        human_bytes(m.bytes()),
        m.threads,
        if m.threads == 1 { "" } else { "s" },
        human_bytes(m.per_row),
        human_bytes(m.images)
    )
}

/// Refuses a render that needs more than `limit` bytes of memory (default: 75% of
/// physical RAM; a saturated need is always refused). Checked before any allocation.
pub fn check_memory(m: &StreamingMemory, limit: Option<u64>) -> anyhow::Result<()> {
    let limit = limit.unwrap_or_else(|| physical_memory().map_or(u64::MAX, |m| m / 4 * 3));
    let need = m.bytes();
    ensure!(
        need <= limit && need != u64::MAX,
        "the render needs {} of memory but the limit is {} (--max-memory, default 75% of RAM); lower --width, --bins or --threads",
        describe_memory(m),
        human_bytes(limit)
    );
    Ok(())
}

/// Refuses an output `out` when `what` (`need` bytes) would not fit in the free space of
/// its filesystem (as an unprivileged user sees it). Where the free space cannot be
/// known (`statvfs` fails), it is not checked.
pub fn check_disk(out: &Path, need: u64, what: &str) -> anyhow::Result<()> {
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if let Ok(fs) = rustix::fs::statvfs(parent) {
        let free = fs.f_bavail.saturating_mul(fs.f_frsize);
        ensure!(
            need <= free && need != u64::MAX,
            "--out {}: {what} needs {} on disk but only {} are free there; lower --width, --height or --bins, or write elsewhere",
            out.display(),
            human_bytes(need),
            human_bytes(free)
        );
    }
    Ok(())
}
