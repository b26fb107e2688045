//! `harvemu replay` streams its trace and keeps nothing per frame it plays: the peak memory of a
//! replay does not grow with the trace, whether its frames are skipped (`--skip-emulated`) or
//! replayed. Alone in its test binary, because it reads the peak of every child this process has
//! waited for (`RUSAGE_CHILDREN`, the kernel's high-water mark of each). Run by name in the
//! optimised build (`--profile vm --test cli_replay_memory`), where two million replayed frames
//! take seconds; a plain `cargo test` leaves it out (scripts/test).

mod common;

use common::{harvemu, scratch};
use std::io::Write;
use std::path::Path;

/// A candump log of `n` frames `gap_us` apart. Skipped: all from the monitor (emulated, so left
/// out with `--skip-emulated`) but every thousandth, a base frame that is replayed. Replayed: a
/// base frame with no data from nobody the harvester emulates, every one replayed.
fn trace(path: &Path, n: u64, gap_us: u64, skipped: bool) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for i in 0..n {
        let us = 1_000_000 + i * gap_us;
        let frame = if !skipped || i % 1000 == 0 {
            "123#"
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

/// Replays `path` as fast as possible; the replay's counts of replayed and refused frames.
fn replay(path: &Path, skip: bool) -> (u64, u64) {
    let mut args = vec!["replay", path.to_str().unwrap(), "--fast"];
    if skip {
        args.push("--skip-emulated");
    }
    let out = harvemu(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let count = |word: &str| -> u64 {
        let at = err.find(word).unwrap_or_else(|| panic!("no '{word}' in {err}"));
        err[..at].split_whitespace().last().unwrap().parse().unwrap()
    };
    (count(" replayed"), count(" refused"))
}

#[test]
fn peak_memory_does_not_grow_with_the_trace() {
    let dir = scratch("cli_replay_memory", "peak");
    let path = |name: &str| dir.join(name);
    // Base frames without data are 44 bits and up to 9 stuff bits: 212 µs at 250 kbit/s, so
    // 400 µs apart they all go out between the harvester's own frames.
    trace(&path("10k.log"), 10_000, 1, true);
    trace(&path("100k.log"), 100_000, 400, false);
    trace(&path("2m.log"), 2_000_000, 400, false);
    trace(&path("1m.log"), 1_000_000, 1, true);
    // Each peak is the maximum over the children so far: more than the last only if this
    // child's is.
    assert_eq!(replay(&path("10k.log"), true), (10, 0));
    assert_eq!(replay(&path("100k.log"), false), (100_000, 0));
    let peak_small = children_peak_kb();
    assert_eq!(replay(&path("2m.log"), false), (2_000_000, 0));
    let peak_replayed = children_peak_kb();
    assert!(std::fs::metadata(path("1m.log")).unwrap().len() > 40_000_000);
    assert_eq!(replay(&path("1m.log"), true), (1000, 0));
    let peak_skipped = children_peak_kb();
    eprintln!(
        "peak RSS: 100,000 replayed {peak_small} kB, 2,000,000 replayed {peak_replayed} kB, \
         1,000,000 read (1000 replayed) {peak_skipped} kB"
    );
    // Keeping 31 bytes per replayed frame would add 59 MB; 2 MB is the whole allowance.
    assert!(
        peak_replayed < peak_small + 2_000,
        "peak RSS {peak_replayed} kB for 2,000,000 replayed frames, {peak_small} kB for 100,000"
    );
    // Holding the records read (about 40 bytes each) would add 40 MB.
    assert!(
        peak_skipped < peak_small + 2_000,
        "peak RSS {peak_skipped} kB for 1,000,000 frames read, {peak_small} kB for 100,000"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
