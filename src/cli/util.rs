//! Small helpers shared by subcommands: sizes, memory, thread pools.

use anyhow::Context;

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

/// Parses "512M", "8G", "1.5GB", "1000000" (decimal units) into bytes.
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim().to_ascii_uppercase();
    let t = t.strip_suffix('B').unwrap_or(&t);
    let (num, mult) = match t.chars().last() {
        Some('K') => (&t[..t.len() - 1], 1e3),
        Some('M') => (&t[..t.len() - 1], 1e6),
        Some('G') => (&t[..t.len() - 1], 1e9),
        Some('T') => (&t[..t.len() - 1], 1e12),
        _ => (t, 1.0),
    };
    match num.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok((v * mult) as u64),
        _ => Err(format!("'{s}' is not a size such as 512M or 8G")),
    }
}

/// Physical memory in bytes (from /proc/meminfo), if known.
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Refuses accumulators of `need` bytes above `limit` (default: 75% of physical RAM;
/// a saturated `need` is always refused).
pub fn check_memory(need: u64, limit: Option<u64>) -> anyhow::Result<()> {
    let limit = limit.unwrap_or_else(|| physical_memory().map_or(u64::MAX, |m| m / 4 * 3));
    anyhow::ensure!(
        need <= limit && need != u64::MAX,
        "the accumulators need {} but the limit is {} (--max-memory, default 75% of RAM); lower --width/--height/--bins",
        human_bytes(need),
        human_bytes(limit)
    );
    Ok(())
}

/// Runs `f` on a rayon pool of `threads` threads (all cores when `None`).
pub fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        anyhow::ensure!(n >= 1, "--threads must be at least 1");
        b = b.num_threads(n);
    }
    let pool = b.build().context("cannot start the thread pool")?;
    Ok(pool.install(f))
}

/// Total size of a file or of the files in a directory.
pub fn disk_size(path: &std::path::Path) -> u64 {
    if path.is_dir() {
        std::fs::read_dir(path)
            .map(|it| it.flatten().map(|e| disk_size(&e.path())).sum())
            .unwrap_or(0)
    } else {
        std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_bytes("512M"), Ok(512_000_000));
        assert_eq!(parse_bytes("8g"), Ok(8_000_000_000));
        assert_eq!(parse_bytes("1.5GB"), Ok(1_500_000_000));
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert!(parse_bytes("-1G").is_err());
        assert!(parse_bytes("lots").is_err());
    }
}
