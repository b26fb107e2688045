//! The harvester's own DBC imported: the network it gives sends every cyclic message of the DBC
//! with its identifier, length and period (cantools reads them from the DBC), as the harvester
//! itself does for those that are alone on their identifier; the import names the monitor's
//! event messages as not generated and says that the protocol logic is not in a DBC. The python
//! is `$HARVEMU_PYTHON`, else `python3`, with cantools (the test fails, never skips, without).

mod common;

use common::{harvemu, scratch};
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

/// Per BO_ of the DBC argv[1] with a cycle time: its length and period; per identifier of the
/// candump logs argv[2..]: its frame lengths, count, period (ms, the least-squares slope) and
/// shortest gap.
const PERIODS: &str = r##"
import json, sys, cantools
db = cantools.database.load_file(sys.argv[1], strict=False)
cyclic = {f"{m.frame_id:08X}": {"length": m.length, "cycle": m.cycle_time, "name": m.name}
          for m in db.messages if m.cycle_time}
logs = []
for path in sys.argv[2:]:
    seen = {}
    for line in open(path):
        t, _, frame = line.split()
        ident, data = frame.split("#")
        seen.setdefault(ident, []).append((float(t[1:-1]), len(data) // 2))
    def slope(v):
        # Least squares of time against frame number: arbitration delays a frame now and then,
        # by a few frame times, but not the schedule it keeps.
        n = len(v)
        if n < 2:
            return None
        mi, mt = (n - 1) / 2, sum(t for t, _ in v) / n
        num = sum((i - mi) * (t - mt) for i, (t, _) in enumerate(v))
        den = sum((i - mi) ** 2 for i in range(n))
        return num / den * 1000
    logs.append({i: {"lengths": sorted({n for _, n in v}), "count": len(v), "period": slope(v),
                     "shortest": min((b[0] - a[0] for a, b in zip(v, v[1:])), default=0) * 1000}
                 for i, v in seen.items()})
print(json.dumps({"cyclic": cyclic, "logs": logs}))
"##;

#[test]
fn the_harvesters_dbc_imported_sends_its_cyclic_messages_at_their_periods() {
    let dir = scratch("import-harvester", "periods");
    let dbc = dir.join("harvester.dbc");
    ok(&["dbc", "-o", s(&dbc)]);
    let net = dir.join("net");
    let said = ok(&["import", s(&dbc), "--out", s(&net)]);
    for event in ["row_command_A0", "flow_F5_to_D0", "flow_F5_to_D5"] {
        assert!(
            said.contains(&format!("warning: {event} (0x"))
                && said.contains("no cycle time: an event message"),
            "{event}: {said}"
        );
    }
    assert!(
        said.contains("a DBC holds no protocol logic (requests, acknowledgements, calibration, states)"),
        "{said}"
    );
    let imported = dir.join("imported.log");
    ok(&[
        "run",
        s(&net.join("network.ron")),
        "--fast",
        "--for",
        "60s",
        "--record",
        s(&imported),
    ]);
    let own = dir.join("harvester.log");
    ok(&["run", "--fast", "--for", "60s", "--record", s(&own)]);

    let py = std::env::var("HARVEMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&py)
        .args(["-c", PERIODS, s(&dbc), s(&imported), s(&own)])
        .output()
        .unwrap_or_else(|e| panic!("cannot run `{py}`: {e}; set HARVEMU_PYTHON to a python with cantools"));
    assert!(
        out.status.success(),
        "the cantools script failed (HARVEMU_PYTHON needs cantools): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let cyclic = v["cyclic"].as_object().unwrap();
    let (imported, own) = (&v["logs"][0], &v["logs"][1]);
    assert!(cyclic.len() >= 20, "{cyclic:?}");
    // One bit time at 250 kbit/s, in ms.
    const BIT_MS: f64 = 0.004;
    let mut alone = 0;
    for (id, m) in cyclic {
        let got = &imported[id];
        let cycle = m["cycle"].as_f64().unwrap();
        assert_eq!(
            got["lengths"],
            serde_json::json!([m["length"]]),
            "{id} {m}: {got}"
        );
        let period = got["period"].as_f64().unwrap();
        assert!((period - cycle).abs() <= BIT_MS, "{id} {m}: period {period} ms");
        // 60 s of it, from time 0.
        let count = got["count"].as_f64().unwrap();
        assert!(
            (count - 60_000.0 / cycle).abs() <= 1.0,
            "{id} {m}: {count} frames"
        );
        // Where the harvester sends one message alone on the identifier, the same period and
        // length (the flow sensors' groups share theirs, and the speed set-point waits for
        // cruise).
        // (An alarm module also sends on change: a gap well under its heartbeat shows it.)
        let theirs = &own[id];
        let steady = theirs["shortest"].as_f64().is_some_and(|g| g > cycle * 0.9);
        let alone_there = theirs["lengths"].as_array().is_some_and(|l| l.len() == 1);
        if alone_there && theirs["count"].as_u64() >= Some(30) && steady {
            assert_eq!(theirs["lengths"], got["lengths"], "{id}");
            let p = theirs["period"].as_f64().unwrap();
            assert!(
                (p - period).abs() <= BIT_MS,
                "{id}: harvester {p} ms, imported {period} ms"
            );
            alone += 1;
        }
    }
    assert!(
        alone >= 10,
        "{alone} identifiers compared with the harvester's own"
    );
}
