//! The DBC codec against cantools: random messages (both byte orders, signed and unsigned,
//! scaled, multiplexed, base and extended ids) built and encoded by cantools, then read and
//! encoded by [`protocol::database`]; every payload must be the same bytes. The python is
//! `$HARVEMU_PYTHON`, else `python3`, and must have cantools (the test fails, never skips,
//! without it).

use protocol::database::Database;
use serde_json::Value;
use std::collections::BTreeMap;
use std::process::Command;

/// Builds a random database with cantools (seed argv[1]) and encodes random values in each
/// message; prints the DBC text and the cases.
const GENERATE: &str = r#"
import json, random, sys
import cantools
from cantools.database.can import Message, Signal, Database, Node
from cantools.database.conversion import BaseConversion

rnd = random.Random(int(sys.argv[1]))

def motorola_positions(start, length):
    out, p = [], start
    for i in range(length):
        out.append(p)
        p = p + 15 if p % 8 == 0 else p - 1
    return out

def place(used, dlc, length, big):
    for _ in range(200):
        if big:
            start = rnd.randrange(dlc * 8)
            pos = motorola_positions(start, length)
        else:
            start = rnd.randrange(dlc * 8 - length + 1)
            pos = list(range(start, start + length))
        if all(0 <= p < dlc * 8 and p not in used for p in pos):
            used.update(pos)
            return start
    return None

messages, cases = [], []
for k in range(40):
    dlc = rnd.randint(1, 8)
    used, signals = set(), []
    mux = dlc >= 3 and rnd.random() < 0.3
    if mux:
        signals.append(Signal("Mux", 0, 8, byte_order="little_endian", is_multiplexer=True))
        used.update(range(8))
    groups = [None] if not mux else [0, 1, 2]
    for g in groups:
        gused = set(used)
        for j in range(rnd.randint(1, 4)):
            length = rnd.choice([1, 2, 3, 4, 7, 8, 11, 12, 16, 20, 24, 32])
            length = min(length, dlc * 8 - 8 * mux)
            big = rnd.random() < 0.5
            start = place(gused, dlc, length, big)
            if start is None:
                continue
            scale = rnd.choice([1, 0.5, 0.125, 2, 0.1, 10])
            offset = rnd.choice([0, -40, 100, 0.5])
            signals.append(Signal(f"S{k}_{j}" + ("" if g is None else f"_m{g}"), start, length,
                                  byte_order="big_endian" if big else "little_endian",
                                  is_signed=rnd.random() < 0.4,
                                  conversion=BaseConversion.factory(scale=scale, offset=offset),
                                  multiplexer_ids=None if g is None else [g],
                                  multiplexer_signal=None if g is None else "Mux"))
    extended = rnd.random() < 0.7
    fid = rnd.randrange(1 << 29) if extended else rnd.randrange(1 << 11)
    m = Message(frame_id=fid, name=f"M{k}", length=dlc, signals=signals, is_extended_frame=extended,
                senders=["N"], strict=True)
    messages.append(m)
db = Database(messages=messages, nodes=[Node("N")], strict=True)
text = db.as_dbc_string()
db = cantools.database.load_string(text, database_format="dbc", strict=True)
for m in db.messages:
    for _ in range(5):
        g = rnd.choice([0, 1, 2]) if m.is_multiplexed() else None
        values = {}
        for s in m.signals:
            if s.is_multiplexer:
                values[s.name] = g
                continue
            if s.multiplexer_ids is not None and g not in s.multiplexer_ids:
                continue
            lo = -(1 << (s.length - 1)) if s.is_signed else 0
            hi = (1 << (s.length - 1)) - 1 if s.is_signed else (1 << s.length) - 1
            raw = rnd.randint(lo, hi)
            values[s.name] = raw * s.scale + s.offset
        data = m.encode(values, scaling=True, strict=False)
        cases.append({"message": m.name, "values": values, "data": data.hex()})
print(json.dumps({"dbc": text, "cases": cases}))
"#;

fn cantools(seed: u64) -> Value {
    let py = std::env::var("HARVEMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&py)
        .args(["-c", GENERATE, &seed.to_string()])
        .output()
        .unwrap_or_else(|e| panic!("cannot run `{py}`: {e}; set HARVEMU_PYTHON to a python with cantools"));
    assert!(
        out.status.success(),
        "the cantools script failed (HARVEMU_PYTHON must have cantools): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON from the script")
}

#[test]
fn payloads_are_the_bytes_cantools_encodes() {
    let mut checked = 0;
    for seed in 1..=5 {
        let made = cantools(seed);
        let text = made["dbc"].as_str().unwrap();
        let db = Database::parse("random.dbc", text).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert!(db.warnings.is_empty(), "seed {seed}: {:?}", db.warnings);
        for case in made["cases"].as_array().unwrap() {
            let name = case["message"].as_str().unwrap();
            let m = db
                .message(name)
                .unwrap_or_else(|| panic!("seed {seed}: no message {name}"));
            let values: BTreeMap<String, f64> = case["values"]
                .as_object()
                .unwrap()
                .iter()
                .map(|(k, v)| (k.clone(), v.as_f64().unwrap()))
                .collect();
            let ours: String = m
                .encode(&values)
                .unwrap_or_else(|| panic!("seed {seed}: {name} {values:?} not encoded"))
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
            let theirs = case["data"].as_str().unwrap();
            assert_eq!(ours, theirs, "seed {seed}: {name} {values:?}\n{m:?}");
            // And back: every value read out of cantools' payload.
            let bytes: Vec<u8> = (0..theirs.len() / 2)
                .map(|i| u8::from_str_radix(&theirs[2 * i..2 * i + 2], 16).unwrap())
                .collect();
            for (signal, want) in &values {
                let s = m.signal(signal).unwrap();
                let got = s.physical(s.extract(&bytes).unwrap());
                assert!(
                    (got - want).abs() <= 1e-9 * want.abs().max(1.0),
                    "seed {seed}: {name}.{signal}: {got} vs {want}"
                );
            }
            checked += 1;
        }
    }
    assert!(checked >= 1000, "{checked} payloads");
}
