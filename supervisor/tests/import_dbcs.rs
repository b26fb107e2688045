//! The two test DBCs of `tests/dbc/` (a J1939 tractor, a sprayer on an OEM bus), each imported
//! with moving signals and run for 10 minutes of bus time: cantools reads from the DBC every
//! cyclic message's identifier, length and cycle time, finds each in the trace at its period
//! (least-squares, within one bit time) and decodes every frame to values within the signal's
//! range (what `--signals walk` moves in). `harvemu dbc` of the imported network gives back the
//! DBC: cantools finds the same nodes, messages, signals and cycle times. Run by name in the
//! optimised build (`--profile vm --test import_dbcs`), where ten minutes of a bus take seconds;
//! a plain `cargo test` leaves it out (scripts/test). The python is `$HARVEMU_PYTHON`, else
//! `python3`, with cantools (the test fails, never skips, without it).

mod common;

use common::{harvemu, root, scratch};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = harvemu(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "harvemu {args:?}: {err}");
    err
}

fn python(script: &str, args: &[&str]) -> Value {
    let py = std::env::var("HARVEMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&py)
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run `{py}`: {e}; set HARVEMU_PYTHON to a python with cantools"));
    assert!(
        out.status.success(),
        "the cantools script failed (HARVEMU_PYTHON needs cantools): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON from the script")
}

/// The trace argv[2] against the DBC argv[1]: per cyclic message, frames, lengths and period
/// (least squares of time on frame number, ms); frames of no message; decoded values outside
/// their signal's range (by more than half a step).
const CHECK: &str = r##"
import json, sys, cantools
db = cantools.database.load_file(sys.argv[1], strict=False)
by_id = {(m.frame_id, m.is_extended_frame): m for m in db.messages}
seen, unknown, outside, decoded = {}, 0, [], 0
for line in open(sys.argv[2]):
    t, _, frame = line.split()
    ident, data = frame.split("#")
    key = (int(ident, 16), len(ident) == 8)
    m = by_id.get(key)
    if m is None:
        unknown += 1
        continue
    payload = bytes.fromhex(data)
    seen.setdefault(m.name, []).append((float(t[1:-1]), len(payload)))
    values = m.decode(payload, decode_choices=False, scaling=True)
    decoded += 1
    for name, v in values.items():
        s = m.get_signal_by_name(name)
        if s.minimum is None or s.maximum is None or s.minimum >= s.maximum:
            continue
        half = abs(s.scale) / 2
        if not (s.minimum - half <= v <= s.maximum + half):
            outside.append(f"{m.name}.{name}={v} [{s.minimum}, {s.maximum}]")
def slope(v):
    n = len(v)
    if n < 2:
        return None
    mi, mt = (n - 1) / 2, sum(t for t, _ in v) / n
    num = sum((i - mi) * (t - mt) for i, (t, _) in enumerate(v))
    return num / sum((i - mi) ** 2 for i in range(n)) * 1000
cyclic = {}
for m in db.messages:
    if m.cycle_time:
        v = seen.get(m.name, [])
        cyclic[m.name] = {"cycle": m.cycle_time, "length": m.length, "count": len(v),
                          "lengths": sorted({n for _, n in v}), "period": slope(v)}
events = [m.name for m in db.messages if not m.cycle_time and m.name in seen]
print(json.dumps({"cyclic": cyclic, "unknown": unknown, "outside": outside[:10],
                  "outside_count": len(outside), "decoded": decoded, "events_sent": events,
                  "bitrate": db.buses[0].baudrate if db.buses else None}))
"##;

/// Two DBCs compared as cantools reads them: nodes, messages (id, format, length, senders,
/// cycle time) and every signal's layout, scaling, range, unit, receivers and multiplexing.
const COMPARE: &str = r##"
import json, sys, cantools
def summary(path):
    db = cantools.database.load_file(path, strict=False)
    def sig(s):
        return [s.name, s.start, s.length, s.byte_order, s.is_signed, s.scale, s.offset,
                s.minimum, s.maximum, s.unit or "", sorted(s.receivers), s.is_multiplexer,
                sorted(s.multiplexer_ids or []), s.multiplexer_signal,
                sorted((int(k), str(v)) for k, v in (s.choices or {}).items())]
    return {
        "nodes": sorted(n.name for n in db.nodes),
        "messages": {m.name: [m.frame_id, m.is_extended_frame, m.length, sorted(m.senders),
                              m.cycle_time, [sig(s) for s in m.signals]] for m in db.messages},
    }
a, b = summary(sys.argv[1]), summary(sys.argv[2])
diff = [k for k in a["messages"] if a["messages"][k] != b["messages"].get(k)]
diff += [k for k in b["messages"] if k not in a["messages"]]
print(json.dumps({"nodes": a["nodes"] == b["nodes"], "messages": len(a["messages"]),
                  "signals": sum(len(m[5]) for m in a["messages"].values()), "differ": diff[:5],
                  "first": [a["messages"].get(diff[0]), b["messages"].get(diff[0])] if diff else None}))
"##;

#[test]
fn the_test_dbcs_import_run_at_their_periods_decode_in_range_and_come_back() {
    for (name, bitrate) in [("tractor", 250_000.0), ("sprayer", 500_000.0)] {
        let dir = scratch("import-dbcs", name);
        let dbc = root().join(format!("tests/dbc/{name}.dbc"));
        let net = dir.join("net");
        let said = ok(&["import", s(&dbc), "--out", s(&net), "--signals", "walk"]);
        let network = net.join("network.ron");
        let trace = dir.join(format!("{name}.log"));
        ok(&[
            "run",
            s(&network),
            "--fast",
            "--for",
            "10m",
            "--record",
            s(&trace),
        ]);
        let v = python(CHECK, &[s(&dbc), s(&trace)]);
        assert_eq!(v["unknown"], 0, "{name}: frames of no message");
        assert_eq!(v["outside_count"], 0, "{name}: {}", v["outside"]);
        assert_eq!(
            v["events_sent"],
            serde_json::json!([]),
            "{name}: event messages go out only when asked"
        );
        let bit_ms = 1000.0 / bitrate;
        let cyclic = v["cyclic"].as_object().unwrap();
        assert!(cyclic.len() >= 26, "{name}: {} cyclic messages", cyclic.len());
        for (m, c) in cyclic {
            let cycle = c["cycle"].as_f64().unwrap();
            assert_eq!(c["lengths"], serde_json::json!([c["length"]]), "{name} {m}: {c}");
            let count = c["count"].as_f64().unwrap();
            assert!(
                (count - 600_000.0 / cycle).abs() <= 1.0,
                "{name} {m}: {count} frames in 10 minutes at {cycle} ms"
            );
            let period = c["period"].as_f64().unwrap();
            assert!(
                (period - cycle).abs() <= bit_ms,
                "{name} {m}: period {period} ms, cycle {cycle} ms"
            );
        }
        eprintln!(
            "{name}: {} cyclic messages at their periods, {} frames decoded in range; {}",
            cyclic.len(),
            v["decoded"],
            said.lines().last().unwrap_or("")
        );

        let again = dir.join("again.dbc");
        ok(&["dbc", "--config", s(&network), "-o", s(&again)]);
        let cmp = python(COMPARE, &[s(&dbc), s(&again)]);
        assert_eq!(cmp["differ"], serde_json::json!([]), "{name}: {}", cmp["first"]);
        assert_eq!(cmp["nodes"], true, "{name}");
        assert!(cmp["messages"].as_u64() >= Some(30), "{name}: {cmp}");
    }
}
