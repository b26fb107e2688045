//! `harvemu replay` streams its trace: the peak memory of a replay of a million-frame candump log
//! is that of a replay of ten thousand frames, not 40 MB more. Alone in its test binary, because
//! it reads the peak of every child this process has waited for (`RUSAGE_CHILDREN`).

mod common;

use common::{harvemu, scratch};
use std::io::Write;
use std::path::Path;

/// A candump log of `n` frames 1 µs apart: all from the monitor (emulated, so skipped with
/// `--skip-emulated`) but every thousandth, a base frame that is replayed.
fn trace(path: &Path, n: u64) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for i in 0..n {
        let us = 1_000_000 + i;
        let frame = if i % 1000 == 0 {
            "123#0102"
        } else {
            "0300A0F5#0101020304050607"
        };
        writeln!(out, "({}.{:06}) harv0 {frame}", us / 1_000_000, us % 1_000_000).unwrap();
    }
    out.flush().unwrap();
}

/// The largest resident set of any child waited for so far, in kB (Linux counts in KiB).
fn children_peak_kb() -> i64 {
    // SAFETY: getrusage only writes the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    assert_eq!(unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) }, 0);
    usage.ru_maxrss
}

/// Replays `path` as fast as possible; the replay's count of replayed frames.
fn replay(path: &Path) -> u64 {
    let out = harvemu(&["replay", path.to_str().unwrap(), "--fast", "--skip-emulated"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let at = err.find(" replayed").unwrap_or_else(|| panic!("{err}"));
    err[..at].split_whitespace().last().unwrap().parse().unwrap()
}

#[test]
fn peak_memory_does_not_grow_with_the_trace() {
    let dir = scratch("cli_replay_memory", "peak");
    let (small, large) = (dir.join("10k.log"), dir.join("1m.log"));
    trace(&small, 10_000);
    trace(&large, 1_000_000);
    assert!(std::fs::metadata(&large).unwrap().len() > 40_000_000);
    assert_eq!(replay(&small), 10);
    let peak_small = children_peak_kb();
    assert_eq!(replay(&large), 1000);
    // The maximum over both children: at least the small one's, more only if the large one's is.
    let peak_large = children_peak_kb();
    eprintln!("peak RSS: 10,000 frames {peak_small} kB, 1,000,000 frames {peak_large} kB");
    // Holding the records (about 40 bytes each) would add 40 MB; allow half of that for noise.
    assert!(
        peak_large < peak_small + 20_000,
        "peak RSS {peak_large} kB for 1,000,000 frames, {peak_small} kB for 10,000"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
