//! The peak resident memory of a run (its wall and CPU seconds come from the test's
//! summary).
//!
//! The peak is the kernel's high-water mark of the process (`VmHWM` in
//! `/proc/self/status`), reset before each run by writing `5` to `/proc/self/clear_refs`
//! (Linux 4.0 and later), so that runs of one study in one process get their own peaks.
//! Where either file is missing (other systems, restricted containers) the peak is
//! reported as unknown, never guessed.

/// Resets the process's peak resident memory; `false` where the platform does not allow
/// it (the next peak is then the process's since its start).
pub fn reset_peak_memory() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The process's peak resident memory since its start or the last reset (bytes), when
/// the platform reports it.
pub fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_high_water_mark(&status)
}

/// `VmHWM:   123456 kB` of a `/proc/PID/status` text, in bytes.
fn parse_high_water_mark(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let mut words = line.split_whitespace().skip(1);
    let value: u64 = words.next()?.parse().ok()?;
    match words.next()? {
        "kB" => value.checked_mul(1024),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_high_water_mark_is_read_in_bytes() {
        let text = "Name:\tx\nVmPeak:\t  2000 kB\nVmHWM:\t    1536 kB\nVmRSS:\t 1000 kB\n";
        assert_eq!(parse_high_water_mark(text), Some(1536 * 1024));
        assert_eq!(parse_high_water_mark("VmHWM: 12 MB\n"), None);
        assert_eq!(parse_high_water_mark("VmRSS: 12 kB\n"), None);
    }

    #[test]
    fn a_peak_is_reported_where_the_platform_has_one() {
        if std::path::Path::new("/proc/self/status").exists() {
            // `black_box`: an optimised build would otherwise drop the unused allocation.
            let big = std::hint::black_box(vec![1u8; 64 << 20]);
            let peak = peak_memory().expect("Linux reports VmHWM");
            assert!(peak >= 64 << 20, "{peak} after touching 64 MiB");
            drop(big);
        }
    }
}
