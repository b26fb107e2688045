//! Resident memory (VmRSS) over a long run, and whether it stayed flat.
//!
//! Contract: [`vm_rss_kib`] reads the process's resident set from `/proc/self/status` (Linux;
//! `None` elsewhere or when it cannot be read). [`Samples::verdict`] is plain arithmetic: memory
//! is flat when the last sample is within [`ALLOWED_GROWTH_PERCENT`] % (at least
//! [`ALLOWED_GROWTH_KIB`]) of the first sample taken after the warm-up, an eighth of the run in
//! which the statistics' tables fill and the allocator settles.

/// Growth allowed after the warm-up, percent of the warm-up sample.
pub const ALLOWED_GROWTH_PERCENT: u64 = 10;
/// Growth always allowed, KiB (allocator noise).
pub const ALLOWED_GROWTH_KIB: u64 = 8 * 1024;

/// The `VmRSS:` line of a `/proc/<pid>/status` text, in KiB.
pub fn parse_vm_rss(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let mut words = line["VmRSS:".len()..].split_whitespace();
    let value: u64 = words.next()?.parse().ok()?;
    (words.next()? == "kB").then_some(value)
}

/// This process's resident set, KiB.
pub fn vm_rss_kib() -> Option<u64> {
    parse_vm_rss(&std::fs::read_to_string("/proc/self/status").ok()?)
}

/// RSS samples over a run: (virtual seconds, KiB).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Samples {
    /// Length of the run, virtual seconds.
    pub duration_s: f64,
    /// The samples, in time order.
    pub points: Vec<(f64, u64)>,
}

impl Samples {
    /// The sample the end is compared with: the first at or after an eighth of the run.
    pub fn baseline(&self) -> Option<(f64, u64)> {
        let warm = self.duration_s / 8.0;
        self.points.iter().copied().find(|(t, _)| *t >= warm)
    }

    /// Flat or not, and the growth from the baseline to the end, KiB (None without samples).
    pub fn verdict(&self) -> Option<(bool, i64)> {
        let (_, base) = self.baseline()?;
        let (_, end) = *self.points.last()?;
        let allowed = (base * ALLOWED_GROWTH_PERCENT / 100).max(ALLOWED_GROWTH_KIB);
        Some((end <= base + allowed, end as i64 - base as i64))
    }

    /// One line: every sample, then the verdict.
    pub fn line(&self) -> String {
        let mib = |k: u64| k as f64 / 1024.0;
        let points: Vec<String> = self
            .points
            .iter()
            .map(|(t, k)| format!("{:.1} h {:.1} MiB", t / 3600.0, mib(*k)))
            .collect();
        let verdict = match (self.verdict(), self.baseline()) {
            (Some((flat, growth)), Some((t, _))) => format!(
                "{} ({:+.1} MiB since {:.1} h)",
                if flat { "flat" } else { "GROWING" },
                growth as f64 / 1024.0,
                t / 3600.0
            ),
            _ => "not measured (no /proc/self/status)".to_string(),
        };
        format!("memory (VmRSS): {}: {verdict}", points.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_resident_set_is_read_from_its_line() {
        let status = "Name:\tharvemu\nVmPeak:\t  200000 kB\nVmRSS:\t   23456 kB\nThreads:\t1\n";
        assert_eq!(parse_vm_rss(status), Some(23456));
        assert_eq!(parse_vm_rss("VmRSS:\t12 MB\n"), None);
        assert_eq!(parse_vm_rss("Name:\tx\n"), None);
        assert_eq!(parse_vm_rss("VmRSS:\n"), None);
    }

    #[test]
    fn this_process_has_a_resident_set_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(vm_rss_kib().is_some_and(|k| k > 0));
        }
    }

    fn samples(points: &[(f64, u64)]) -> Samples {
        Samples {
            duration_s: 80.0,
            points: points.to_vec(),
        }
    }

    #[test]
    fn growth_is_measured_from_the_end_of_the_warm_up() {
        // Start-up growth (before 10 s) does not count; 40 MiB + 10 % is allowed after it.
        let s = samples(&[(0.0, 10_000), (10.0, 40_960), (40.0, 41_000), (80.0, 45_000)]);
        assert_eq!(s.baseline(), Some((10.0, 40_960)));
        assert_eq!(s.verdict(), Some((true, 4040)));
        let s = samples(&[(0.0, 10_000), (10.0, 40_960), (80.0, 40_960 + 4096 + 8192 + 1)]);
        assert_eq!(s.verdict(), Some((false, 12_289)));
        assert!(s.line().contains("GROWING"), "{}", s.line());
        // Small processes get the fixed allowance.
        let s = samples(&[(10.0, 1000), (80.0, 1000 + 8192)]);
        assert_eq!(s.verdict(), Some((true, 8192)));
        assert_eq!(samples(&[(1.0, 5)]).verdict(), None);
    }
}
