//! An hour's soak recorded as MF4 and as BLF: the soak's own memory samples stay flat while the
//! writer streams (`harvemu soak` exits 1 when they grow), and the file reads back whole, every
//! frame the soak counted on the bus. Run by name in the optimised build (`--profile vm --test
//! soak_traces`), where an hour of the harvester takes seconds; a plain `cargo test` leaves it
//! out (scripts/test).

mod common;

use common::{harvemu, scratch};

/// The number after `label` in `text` (`bus: 105098 frames`).
fn number_after(text: &str, label: &str) -> u64 {
    let rest = &text[text
        .find(label)
        .unwrap_or_else(|| panic!("no {label:?} in {text}"))
        + label.len()..];
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn an_hours_soak_writes_mf4_and_blf_with_memory_flat_and_every_frame_in_them() {
    let dir = scratch("soak-traces", "hour");
    for ext in ["mf4", "blf"] {
        let trace = dir.join(format!("hour.{ext}"));
        let path = trace.to_str().unwrap();
        let started = std::time::Instant::now();
        let out = harvemu(&["soak", "--hours", "1", "--record", path]);
        let report = String::from_utf8_lossy(&out.stdout).into_owned();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{ext}: {report}\n{err}");
        let memory = report.lines().find(|l| l.starts_with("memory (VmRSS)")).unwrap();
        assert!(memory.contains(": flat ("), "{ext}: {memory}");
        let trace_line = &report[report.find("; trace: ").expect("the trace's counts")..];
        let frames = number_after(trace_line, "trace: ");
        let errors = number_after(trace_line, "frames, ");
        let size = std::fs::metadata(&trace).unwrap().len();
        eprintln!(
            "{ext}: {frames} frames, {size} bytes, soak {:.1} s; {memory}",
            started.elapsed().as_secs_f64()
        );
        let read = harvemu(&["convert", path, "/dev/null", "--format", "log"]);
        let said = String::from_utf8_lossy(&read.stderr).into_owned();
        assert!(read.status.success(), "{said}");
        assert!(
            said.contains(&format!(": {} records", frames + errors)),
            "{ext}: {said}"
        );
    }
}
